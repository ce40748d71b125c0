"""Errors the command line turns into one clear line and exit code 1."""


class UserError(Exception):
    """Bad input from the user (a file, a manifest, an option): message only, exit 1."""
