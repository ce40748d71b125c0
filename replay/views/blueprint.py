"""The one blueprint saved with every recording: tabs a reviewer can read without a manual.

Tabs: Navigation (map + local metric plot with range circles), Ranges & detection
(time series per run), Errors (growing CDF + error series), ANFIS (one tab per model:
MFs and surface per training epoch, then the explanation of each ranging epoch),
KMCDF (one view per target and method). The event log sits on the right of every tab.
With two runs, the map, the local plot and the errors overlay both runs (names tagged
with the run); the other views are side by side, one column per run.
"""

from __future__ import annotations

import rerun.blueprint as rrb

from replay.views.common import Run, groups, part


def _contents(runs: list[Run], *parts: str) -> list[str]:
    return [f"+ {r.path(*parts)}/**" for r in runs]


def _navigation(runs: list[Run]) -> rrb.Container:
    return rrb.Horizontal(
        rrb.MapView(name="Map: GPS truth and every track", contents=_contents(runs, "map")),
        rrb.Spatial2DView(name="Local east/north (m), range circles", contents=_contents(runs, "local")),
        name="Navigation",
    )


def _ranges_column(run: Run) -> rrb.Container:
    tag = f" [{run.label}]" if run.label else ""
    features = [rrb.TimeSeriesView(name=f"{f}{tag}", contents=[f"+ {run.path('series', f)}/**"])
                for f in ("f1_innovation_m", "f2_mahalanobis2", "f3_r_adapted_m2")]
    return rrb.Vertical(
        rrb.TimeSeriesView(name=f"Ranges measured / true (m){tag}", contents=[f"+ {run.path('series', 'range')}/**"]),
        rrb.TimeSeriesView(name=f"Residual measured - true (m){tag}",
                           contents=[f"+ {run.path('series', 'residual')}/**"]),
        rrb.Horizontal(*features),
        rrb.TimeSeriesView(name=f"ANFIS output vs T2 (m){tag}", contents=[f"+ {run.path('series', 'anfis')}/**"]),
        rrb.TimeSeriesView(name=f"Detection lanes (0 = truth label; raised = flagged){tag}",
                           contents=[f"+ {run.path('series', 'lanes')}/**"]),
        row_shares=[2, 1, 1, 1, 2],
    )


def _errors(runs: list[Run], scale: dict[str, float]) -> rrb.Container:
    followers = sorted({str(k[0]) for r in runs for k, _ in groups(r.review.errors, ["follower"])})
    cdfs = []
    for f in followers:
        s = scale.get(f, 1.0)
        bounds = rrb.VisualBounds2D(x_range=[-0.05 * s, 1.1 * s], y_range=[-1.08 * s, 0.05 * s])
        cdfs.append(rrb.Vertical(
            rrb.Spatial2DView(name=f"Error CDF of {f} so far (x: error m; lines at 0/50/90/95/100 %)",
                              contents=[f"+ {r.path('cdf', f)}/**" for r in runs]
                              + [f"- {r.path('cdf', f, 'table')}" for r in runs], visual_bounds=bounds),
            rrb.Horizontal(*(rrb.TextDocumentView(name=f"Percentiles so far{' [' + r.label + ']' if r.label else ''}",
                                                  contents=[f"+ {r.path('cdf', f, 'table')}"]) for r in runs)),
            row_shares=[3, 1]))
    return rrb.Horizontal(
        *cdfs,
        rrb.Vertical(rrb.TimeSeriesView(name="Horizontal error vs GPS (m)", contents=_contents(runs, "series", "error")),
                     *(rrb.TextDocumentView(name=f"Run {r.review.run_id}", contents=[f"+ {r.path('info')}"])
                       for r in runs), row_shares=[3] + [1] * len(runs)),
        name="Errors",
    )


def _anfis_model(run: Run, model: str) -> rrb.Container:
    base = run.path("anfis", model)
    tag = f" [{run.label}]" if run.label else ""
    mf = [rrb.Spatial2DView(name=f"MF input {i} (per epoch on anfis_epoch; kept model on time)", contents=[f"+ {base}/training/mf/in{i}/**"])
          for i in (1, 2, 3)]
    now = [rrb.Spatial2DView(name=f"Input {i} on the final MFs", contents=[f"+ {base}/explain/mf/in{i}/**"])
           for i in (1, 2, 3)]
    return rrb.Horizontal(
        rrb.Vertical(*mf, name="training"),
        rrb.Vertical(rrb.Spatial3DView(name="Output surface (f3 at median)", contents=[f"+ {base}/training/surface",
                                                                                     f"+ {base}/training/axes"]),
                     rrb.TimeSeriesView(name="Training RMSE (m), timeline anfis_epoch", contents=[f"+ {base}/training/rmse"])),
        rrb.Vertical(*now, name="this epoch"),
        rrb.Vertical(rrb.Spatial2DView(name="Rule firing strengths", contents=[f"+ {base}/explain/firing"]),
                     rrb.TextDocumentView(name="Why (not) flagged", contents=[f"+ {base}/explain/verdict"])),
        name=f"{model}{tag}",
    )


def _anfis(runs: list[Run]) -> rrb.Container | None:
    tabs = []
    for run in runs:
        models = {str(k[0]) for k, _ in groups(run.review.anfis_epochs, ["model"])}
        models |= {str(k[0]) for k, _ in groups(run.review.anfis_explain, ["model"])}
        tabs += [_anfis_model(run, part(m)) for m in sorted(models)]
    return rrb.Tabs(*tabs, name="ANFIS") if tabs else None


def _kmcdf(runs: list[Run]) -> rrb.Container | None:
    views = [rrb.Spatial2DView(name=f"KMCDF {target}/{method}" + (f" [{run.label}]" if run.label else "")
                               + " (fixes by cluster, final fix, nodes)",
                               contents=[f"+ {run.path('kmcdf', str(target), str(method))}/**",
                                         f"+ {run.path('local', str(target), 'gps', 'position')}"])
             for run in runs for (target, method), _ in groups(run.review.kmcdf, ["target", "method"])]
    return rrb.Grid(*views, name="KMCDF") if views else None


def build_blueprint(runs: list[Run], scale: dict[str, float], active_tab: int | str = 0) -> rrb.Blueprint:
    """The workstation layout for one run or two compared; `scale` the CDF extents; `active_tab` index or name."""
    tabs = [_navigation(runs), rrb.Horizontal(*(_ranges_column(r) for r in runs), name="Ranges & detection"),
            _errors(runs, scale), _anfis(runs), _kmcdf(runs)]
    main = rrb.Tabs(*(t for t in tabs if t is not None), active_tab=active_tab)
    log = rrb.TextLogView(name="Events", contents=_contents(runs, "events"))
    return rrb.Blueprint(
        rrb.Horizontal(main, log, column_shares=[4, 1]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(timeline="time", state="collapsed"),
    )
