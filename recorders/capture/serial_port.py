"""serial:///dev/ttyUSB0?baud=115200: a serial device (or a pseudo-terminal) through pyserial."""

from __future__ import annotations

from urllib.parse import parse_qs, urlsplit

import serial

from .base import READ_SIZE, Source, SourceClosed, SourceError

DEFAULT_BAUD = 115200


def parse_serial(url: str) -> tuple[str, int]:
    """(device path, baud rate) of a serial:// address."""
    parts = urlsplit(url)
    if not parts.path:
        raise SourceError(f"{url}: expected serial:///dev/DEVICE?baud=N")
    query = parse_qs(parts.query)
    try:
        baud = int(query.get("baud", [DEFAULT_BAUD])[0])
    except ValueError:
        raise SourceError(f"{url}: baud must be an integer") from None
    if baud <= 0:
        raise SourceError(f"{url}: baud must be positive")
    return parts.path, baud


class SerialSource(Source):
    """A serial port in raw mode; a vanished device (USB unplugged, pty closed) is reopened when it is back."""

    def __init__(self, url: str):
        super().__init__(url)
        self.device, self.baud = parse_serial(url)
        self._port = None

    def open(self) -> None:
        """Open and configure the port (raises OSError when the device is absent)."""
        try:
            self._port = serial.Serial(self.device, self.baud, timeout=0)
        except (serial.SerialException, ValueError) as exc:
            raise OSError(str(exc)) from exc

    def fileno(self) -> int:
        """The device's descriptor."""
        assert self._port is not None
        return self._port.fileno()

    def read(self) -> bytes:
        """The bytes waiting; SourceClosed when the device went away."""
        assert self._port is not None
        try:
            return self._port.read(max(1, min(self._port.in_waiting, READ_SIZE)))
        except (serial.SerialException, OSError) as exc:
            raise SourceClosed(str(exc)) from exc

    def close(self) -> None:
        """Close the device."""
        if self._port is not None:
            try:
                self._port.close()
            except OSError:  # an unplugged device may refuse even that
                pass
            self._port = None
