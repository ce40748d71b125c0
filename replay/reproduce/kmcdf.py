"""Reproduce seed 003's Fig. 2: KMCDF and four delay-only baselines against abnormal nodes.

Success probability for N = 6 and N = 4 nodes, every abnormal-node count
0..N, KMCDF1 (abnormal delays), KMCDF2 (abnormal delays and phases), GAR,
EAR, LMS and LHC; a table beside the paper's published numbers, JSON as
docs/design.md section 6 says, a PNG and an .rrd. Points run in
worker processes, each from its own seeded stream, so the numbers do not
depend on the number of workers, nor on whether the workers are a process
pool or a Dask cluster (`client`, see `replay.run.batch.dask_client`).
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, replace
from multiprocessing import get_context
from pathlib import Path
from typing import TYPE_CHECKING

from replay.stack.positioning.kmcdf import KmcdfParams
from replay.stack.positioning.kmcdf_montecarlo import METHODS, success_point

LAYOUTS: tuple[int, ...] = (6, 4)
SENSITIVITY_NOISES: tuple[float, ...] = (0.01, 0.05, 0.1, 0.15, 0.2)
Curves = dict[str, dict[str, dict[str, float]]]        # layout -> method -> k -> rate
Task = tuple[int, int, str, int, int, KmcdfParams]

if TYPE_CHECKING:
    from distributed import Client


@dataclass(frozen=True)
class PaperClaim:
    """One published statement of seed 003 section 4 about Fig. 2."""

    layout: str
    method: str
    abnormal: int
    relation: str     # "=" a reported value, "<" / ">" a bound, "fails" reported as failed
    value: float


PAPER_CLAIMS: tuple[PaperClaim, ...] = (
    PaperClaim("6", "kmcdf1", 3, "=", 0.942),
    PaperClaim("6", "kmcdf2", 3, "=", 0.842),
    PaperClaim("6", "kmcdf1", 6, "=", 0.918),
    PaperClaim("6", "kmcdf2", 4, ">", 0.60),
    PaperClaim("4", "kmcdf1", 2, "=", 0.948),
    PaperClaim("4", "kmcdf2", 2, "=", 0.838),
    PaperClaim("6", "gar", 3, "<", 0.60),
    PaperClaim("6", "ear", 3, "<", 0.20),
    PaperClaim("6", "lhc", 3, "=", 0.23),
    *(PaperClaim("6", "lms", k, "=", 0.0) for k in (3, 4, 5, 6)),
    *(PaperClaim("6", m, 4, "fails", 0.0) for m in ("gar", "ear", "lhc")),
    *(PaperClaim("4", m, 2, "fails", 0.0) for m in ("gar", "ear", "lms", "lhc")),
)


@dataclass(frozen=True)
class KmcdfReproduction:
    """Success rates of every method and layout, with the settings that produced them."""

    trials: int
    seed: int
    phase_noise_rad: float
    layouts: Curves

    def to_json(self) -> dict[str, object]:
        """The object docs/design.md section 6 specifies: phase_noise_rad, trials, layouts (plus the seed)."""
        return {"phase_noise_rad": self.phase_noise_rad, "trials": self.trials,
                "seed": self.seed, "layouts": self.layouts}


def _point(task: Task) -> float:
    """Worker entry: one success rate."""
    n_nodes, k, method, trials, seed, params = task
    return success_point(n_nodes, k, method, trials, seed, params)


@contextmanager
def _single_threaded_blas() -> Iterator[None]:
    """Workers spawned inside inherit one BLAS thread each: threaded LAPACK on 56x56 problems only spins."""
    keys = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
    saved = {k: os.environ.get(k) for k in keys}
    os.environ.update({k: "1" for k in keys})
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def run_tasks(tasks: Sequence[Task], workers: int, client: Client | None = None) -> list[float]:
    """Success rates of `tasks`, in order; on a Dask `client` when given, else `workers` > 1 spawns processes."""
    if workers <= 1 and client is None:
        return [_point(t) for t in tasks]
    # heavy points first so the two cores finish together
    order = sorted(range(len(tasks)), key=lambda i: tasks[i][2] not in ("kmcdf1", "kmcdf2", "lhc"))
    if client is not None:
        results = client.gather(client.map(_point, [tasks[i] for i in order], pure=False))
    else:
        with _single_threaded_blas(), ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
            results = list(pool.map(_point, [tasks[i] for i in order]))
    out = [0.0] * len(tasks)
    for i, r in zip(order, results):
        out[i] = r
    return out


def reproduce(trials: int = 1000, seed: int = 0, params: KmcdfParams = KmcdfParams(),
              workers: int = 2, methods: Sequence[str] = METHODS, client: Client | None = None,
              ) -> KmcdfReproduction:
    """Every point of Fig. 2 for both layouts."""
    tasks: list[Task] = [(n, k, m, trials, seed, params)
                         for n in LAYOUTS for m in methods for k in range(n + 1)]
    rates = run_tasks(tasks, workers, client)
    layouts: Curves = {str(n): {m: {} for m in methods} for n in LAYOUTS}
    for (n, k, m, *_), rate in zip(tasks, rates):
        layouts[str(n)][m][str(k)] = rate
    return KmcdfReproduction(trials, seed, params.sigma_phase_rad, layouts)


SENSITIVITY_POINTS: tuple[tuple[int, int, str], ...] = (
    (6, 0, "kmcdf1"), (6, 3, "kmcdf1"), (6, 6, "kmcdf1"), (6, 3, "kmcdf2"),
    (4, 0, "kmcdf1"), (4, 2, "kmcdf1"), (4, 2, "kmcdf2"),
)


def sensitivity(trials: int = 1000, seed: int = 0, params: KmcdfParams = KmcdfParams(),
                noises: Sequence[float] = SENSITIVITY_NOISES, workers: int = 2, client: Client | None = None,
                ) -> dict[str, dict[str, float]]:
    """KMCDF success at the paper's points for each phase noise: noise -> "N6 kmcdf1 @3" -> rate."""
    tasks: list[Task] = [(n, k, m, trials, seed, replace(params, sigma_phase_rad=s))
                         for s in noises for n, k, m in SENSITIVITY_POINTS]
    rates = iter(run_tasks(tasks, workers, client))
    return {str(s): {f"N{n} {m} @{k}": next(rates) for n, k, m in SENSITIVITY_POINTS}
            for s in noises}


def paper_points(claims: Sequence[PaperClaim] = PAPER_CLAIMS) -> Curves:
    """The paper's reported values (relation "="), shaped like `KmcdfReproduction.layouts`."""
    out: Curves = {}
    for c in claims:
        if c.relation == "=":
            out.setdefault(c.layout, {}).setdefault(c.method, {})[str(c.abnormal)] = c.value
    return out


def format_curves(result: KmcdfReproduction) -> str:
    """The figure as a table: one block per layout, methods by abnormal-node count (percent)."""
    lines = [f"KMCDF reproduction (seed 003, Fig. 2): {result.trials} trials per point, "
             f"phase noise {result.phase_noise_rad:g} rad, seed {result.seed}"]
    for layout, methods in result.layouts.items():
        ks = sorted(int(k) for k in next(iter(methods.values())))
        lines += ["", f"N = {layout}: success (%) by number of abnormal nodes",
                  "method  " + "".join(f"{k:>7d}" for k in ks)]
        for m, pts in methods.items():
            lines.append(f"{m:<8s}" + "".join(f"{100 * pts[str(k)]:7.1f}" for k in ks))
    return "\n".join(lines)


def format_claims(result: KmcdfReproduction, claims: Sequence[PaperClaim] = PAPER_CLAIMS) -> str:
    """Each published statement beside our number: difference in points, or whether a bound holds."""
    lines = ["Against the paper (seed 003 section 4)",
             f"{'N':>2s} {'method':<7s} {'abn':>3s} {'paper':>8s} {'ours':>7s}  verdict"]
    for c in claims:
        ours = result.layouts.get(c.layout, {}).get(c.method, {}).get(str(c.abnormal))
        if ours is None:
            continue
        if c.relation == "=":
            paper, verdict = f"{100 * c.value:.1f}", f"{100 * (ours - c.value):+.1f} points"
        elif c.relation == "fails":
            paper, verdict = "fails", ""
        else:
            holds = ours < c.value if c.relation == "<" else ours > c.value
            paper, verdict = f"{c.relation} {100 * c.value:.0f}", "holds" if holds else "DOES NOT HOLD"
        lines.append(f"{c.layout:>2s} {c.method:<7s} {c.abnormal:>3d} {paper:>8s} "
                     f"{100 * ours:7.1f}  {verdict}")
    return "\n".join(lines)


def format_sensitivity(table: dict[str, dict[str, float]]) -> str:
    """KMCDF success (%) at the paper's points, one row per phase noise."""
    cols = list(next(iter(table.values())))
    lines = ["Phase-noise sensitivity: KMCDF success (%) at the paper's points",
             f"{'sigma_phase':>11s}" + "".join(f"{c:>16s}" for c in cols)]
    for noise, row in table.items():
        lines.append(f"{float(noise):11.2f}" + "".join(f"{100 * row[c]:16.1f}" for c in cols))
    return "\n".join(lines)


def save_png(result: KmcdfReproduction, path: str | Path) -> None:
    """Fig. 2 as a PNG: one panel per layout, the paper's values as open diamonds."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from replay.views.kmcdf import METHOD_COLORS

    paper = paper_points()
    fig, axes = plt.subplots(1, len(result.layouts), figsize=(11, 4.2), sharey=True)
    for ax, (layout, methods) in zip(axes, result.layouts.items()):
        for m, pts in methods.items():
            ks = sorted(int(k) for k in pts)
            color = tuple(c / 255 for c in METHOD_COLORS[m])
            ax.plot(ks, [100 * pts[str(k)] for k in ks], "o-", color=color, label=m.upper())
            ref = paper.get(layout, {}).get(m, {})
            if ref:
                ax.plot([int(k) for k in ref], [100 * v for v in ref.values()], "D",
                        mfc="none", ms=10, color=color, label=f"{m.upper()} (paper)")
        ax.set(title=f"N = {layout}", xlabel="abnormal nodes", ylim=(-3, 103),
               xticks=sorted(int(k) for k in next(iter(methods.values()))))
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("success probability (%)")
    axes[-1].legend(fontsize=7, loc="lower left")
    fig.suptitle(f"KMCDF vs delay-only baselines ({result.trials} trials per point, "
                 f"phase noise {result.phase_noise_rad:g} rad; open diamonds: the paper)")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def save_rrd(result: KmcdfReproduction, path: str | Path) -> None:
    """The same curves in Rerun (imports rerun only here)."""
    from replay.views.kmcdf import save_success_curves

    Path(path).parent.mkdir(parents=True, exist_ok=True)
    save_success_curves(path, result.layouts, paper_points(),
                        recording_id=f"reproduce-kmcdf-seed{result.seed}")
