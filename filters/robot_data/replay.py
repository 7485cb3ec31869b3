"""Replay a robot log through `MonteCarloLocalizer` against its corrected poses.

A *log* here is anything with ``poses (K, 3)`` (reference robot poses, e.g. the
scan-matched poses of a corrected CARMEN log), ``odometry (K, 3)`` (raw increments, row
``k`` from scan ``k - 1`` to scan ``k``), ``scan(k) -> LaserScan`` and ``len()``:
`filters.robot_data.carmen.CarmenLog` is one.

Step ``k`` of a replay: ``predict(odometry[k])`` (not for the first scan of a run), then
``update(scan(k))`` (the localizer's motion gate applies), then the belief's *estimate*
(`estimate`: the mean of its heaviest hypothesis,
what the env scores) is compared with ``poses[k]``: position error ``|est_xy - pose_xy|`` (m)
and heading error ``|wrap(est_theta - pose_theta)|`` (rad).

* `track`: tracking from a Gaussian cloud around the first reference pose.
* `global_localization_trials`: global localization (uniform over free space) from
  several start scans. A trial's outcome is decided at the first step whose belief is
  ``converged`` (`MonteCarloLocalizer.belief`): ``"correct"`` if then the estimate is
  within ``pos_tol_m`` and ``theta_tol_rad`` of the reference pose, else ``"wrong"``;
  ``"unconverged"`` if no step within ``n_steps`` converges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from filters.localization.mcl import MCLConfig, MonteCarloLocalizer
from filters.mapping.grid import GridMap
from filters.numbers import is_int
from filters.pose import wrap_angle

__all__ = ["MapMismatchError", "Track", "TrialResult", "track", "global_localization_trials", "summarize_trials"]

OUTCOMES = ("correct", "wrong", "unconverged")


class MapMismatchError(ValueError):
    """The map does not hold the log's poses: a map of another place, or in another frame (off the map, or
    on its obstacles and unknown cells)."""


def _check_on_map(grid: GridMap, poses: np.ndarray, what: str, min_share: float = 0.9, path: bool = False) -> None:
    """Raise `MapMismatchError` unless at least ``min_share`` of ``poses`` (``(K, 3)``, the map's
    frame, m) lie on ``grid``, and as many off its obstacles; for the poses of a driven ``path``, on its
    free cells. Where the robot drove, its scans saw free space: on the ACES log's own map every pose is
    on a free cell, and with the map shifted 1, 2 or 10 m in x against the log's frame 92, 67 and 45 %
    (-1 m in x: 86 %; +1 m in y: 83 %). Single poses and start sets need only be off the obstacles (a
    docking spot the robot's own body hid may be unknown). ``what`` names the poses in the message."""
    xy = np.asarray(poses, dtype=np.float64).reshape(-1, 3)[:, :2]
    row, col = grid.world_to_cell(xy)
    on = grid.in_bounds(row, col)
    inside = float(np.mean(on))
    if inside < min_share:
        x0, x1, y0, y1 = grid.extent_m
        share = f"({xy[0, 0]:.6g}, {xy[0, 1]:.6g}) lies off" if len(xy) == 1 else f"only {100 * inside:.0f} % lie on"
        raise MapMismatchError(
            f"{what}: {share} the map (x in [{x0:.6g}, {x1:.6g}] m, y in [{y0:.6g}, {y1:.6g}] m): "
            "is it a map of this place, in the log's frame?"
        )
    ok = np.zeros(len(xy), bool)
    if path:
        ok[on] = grid.free_mask()[row[on], col[on]]
    else:
        ok[on] = ~grid.occupied_mask()[row[on], col[on]]
    share = float(np.mean(ok))
    if share < min_share:
        if len(xy) == 1:
            where = f"({xy[0, 0]:.6g}, {xy[0, 1]:.6g}) lies on an obstacle"
        else:
            where = f"only {100 * share:.0f} % lie {'on free cells' if path else 'off the obstacles'}"
        raise MapMismatchError(
            f"{what}: {where} of the map: is the map in the log's frame (its origin, its resolution)?"
        )


@dataclass(frozen=True, eq=False)
class Track:
    """Per-step results of a replay (arrays of length ``n`` steps).

    Attributes:
        scan_index: ``(n,)`` scan of each step.
        estimate: ``(n, 3)`` belief estimates (heaviest hypothesis' mean).
        pos_error_m, theta_error_rad: ``(n,)`` errors against the reference poses.
        pos_std_m: ``(n,)`` belief position std.
        converged: ``(n,)`` bool, ``belief().converged``.
        particles: per step ``(N_k, 3)`` poses if recorded, else an empty list.
    """

    scan_index: np.ndarray
    estimate: np.ndarray
    pos_error_m: np.ndarray
    theta_error_rad: np.ndarray
    pos_std_m: np.ndarray
    converged: np.ndarray
    particles: list

    def stats(self) -> dict:
        """Median, mean, 95th percentile and max of the position error (m) and heading error (deg)."""
        p, t = self.pos_error_m, np.degrees(self.theta_error_rad)
        return {
            "steps": int(p.size),
            "pos_median_m": float(np.median(p)),
            "pos_mean_m": float(np.mean(p)),
            "pos_p95_m": float(np.percentile(p, 95)),
            "pos_max_m": float(np.max(p)),
            "theta_median_deg": float(np.median(t)),
            "theta_p95_deg": float(np.percentile(t, 95)),
            "theta_max_deg": float(np.max(t)),
        }


@dataclass(frozen=True)
class TrialResult:
    """One global-localization trial.

    Attributes:
        start: first scan of the trial.
        outcome: ``"correct"``, ``"wrong"`` or ``"unconverged"``.
        steps: scans processed until the outcome was decided (``n_steps`` run if unconverged).
        pos_error_m, theta_error_rad: errors at that step (the last step if unconverged).
    """

    start: int
    outcome: str
    steps: int
    pos_error_m: float
    theta_error_rad: float


def _check_log(log) -> int:
    for name in ("poses", "odometry", "scan"):
        if not hasattr(log, name):
            raise TypeError(f"log must have poses, odometry and scan(k) (e.g. a CarmenLog), it has no {name!r}")
    n = len(log)
    if n == 0:
        raise ValueError("log has no scans")
    return n


def _config(mcl_config) -> MCLConfig:
    if isinstance(mcl_config, dict):
        return MCLConfig(**mcl_config)
    if mcl_config is None:
        return MCLConfig()
    if not isinstance(mcl_config, MCLConfig):
        raise TypeError(f"mcl_config must be an MCLConfig or a dict, got {type(mcl_config).__name__}")
    return mcl_config


def _errors(est: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    return float(math.hypot(est[0] - ref[0], est[1] - ref[1])), float(abs(wrap_angle(est[2] - ref[2])))


def track(
    log,
    grid: GridMap,
    mcl_config: MCLConfig | dict | None = None,
    rng_seed: int = 0,
    start: int = 0,
    stop: int | None = None,
    init_std=(0.1, 0.1, 0.05),
    global_init: bool = False,
    record_particles: bool = False,
) -> Track:
    """Replay scans ``start .. stop - 1`` from a cloud around ``poses[start]`` (or uniform with ``global_init``).

    Raises `MapMismatchError` (a ``ValueError``) if fewer than 90 % of these scans' reference poses, or
    (tracking) the start pose, lie on ``grid``.

    Args:
        log: see the module docstring.
        grid: the map.
        mcl_config: filter configuration (None = defaults).
        rng_seed: seed of the ``numpy.random.Generator`` the filter draws from.
        start: first scan.
        stop: scan after the last (default: the end of the log).
        init_std: ``(sx m, sy m, stheta rad)`` of the initial cloud (tracking).
        global_init: start uniform over free space instead.
        record_particles: keep a copy of the particles after every step (for animations).
    """
    n = _check_log(log)
    stop = n if stop is None else stop
    if not 0 <= start < stop <= n:
        raise ValueError(f"need 0 <= start < stop <= {n}, got start={start}, stop={stop}")
    _check_on_map(grid, log.poses[start:stop], f"the log's poses (scans {start}-{stop - 1})", path=True)
    if not global_init:
        _check_on_map(grid, log.poses[start], f"the start pose (scan {start})", min_share=1.0)
    mcl = MonteCarloLocalizer(grid, _config(mcl_config), np.random.default_rng(rng_seed))
    if global_init:
        mcl.init_global()
    else:
        mcl.init_around(log.poses[start], init_std)
    steps = stop - start
    est = np.empty((steps, 3))
    pe, te, ps = np.empty(steps), np.empty(steps), np.empty(steps)
    conv = np.zeros(steps, dtype=bool)
    parts: list = []
    for i, k in enumerate(range(start, stop)):
        if i:
            mcl.predict(log.odometry[k])
        mcl.update(log.scan(k))
        b = mcl.belief()
        est[i] = b.estimate
        pe[i], te[i] = _errors(b.estimate, log.poses[k])
        ps[i] = b.pos_std_m
        conv[i] = b.converged
        if record_particles:
            parts.append(np.array(mcl.poses))
    return Track(np.arange(start, stop), est, pe, te, ps, conv, parts)


def global_localization_trials(
    log,
    grid: GridMap,
    mcl_config: MCLConfig | dict | None,
    starts,
    n_steps: int,
    rng_seed: int = 0,
    pos_tol_m: float = 0.5,
    theta_tol_rad: float = math.radians(15.0),
) -> list[TrialResult]:
    """Global localization from each scan in ``starts``, at most ``n_steps`` scans each (see the module docstring).

    Trial ``i`` uses a generator seeded ``(rng_seed, i)``, so results do not depend on the
    other trials. A trial that reaches the end of the log stops there.

    Returns:
        One `TrialResult` per start, in order.

    Raises:
        MapMismatchError: fewer than 90 % of the start scans' reference poses lie on ``grid``.
    """
    n = _check_log(log)
    cfg = _config(mcl_config)
    raw = np.asarray(starts).reshape(-1).tolist()
    if not raw:
        raise ValueError("starts is empty")
    not_int = [s for s in raw if not is_int(s)]
    if not_int:
        raise ValueError(f"starts must be integer scan indices, got {not_int[:5]}")
    starts = [int(s) for s in raw]
    bad = [s for s in starts if not 0 <= s < n]
    if bad:
        raise ValueError(f"starts must be scan indices in [0, {n}), got {bad[:5]}")
    if not (is_int(n_steps) and n_steps >= 1):
        raise ValueError(f"n_steps must be an int >= 1, got {n_steps!r}")
    _check_on_map(grid, log.poses[starts], f"the start scans' poses ({len(starts)} starts)")
    out = []
    for i, s in enumerate(starts):
        mcl = MonteCarloLocalizer(grid, cfg, np.random.default_rng([rng_seed, i]))
        mcl.init_global()
        outcome, steps, pe, te = "unconverged", 0, math.nan, math.nan
        for j, k in enumerate(range(s, min(s + n_steps, n))):
            if j:
                mcl.predict(log.odometry[k])
            mcl.update(log.scan(k))
            b = mcl.belief()
            steps = j + 1
            pe, te = _errors(b.estimate, log.poses[k])
            if b.converged:
                outcome = "correct" if (pe <= pos_tol_m and te <= theta_tol_rad) else "wrong"
                break
        out.append(TrialResult(s, outcome, steps, pe, te))
    return out


def summarize_trials(results: list[TrialResult]) -> dict:
    """Counts per outcome, and the median steps / errors of the correct trials."""
    counts = {o: sum(r.outcome == o for r in results) for o in OUTCOMES}
    ok = [r for r in results if r.outcome == "correct"]
    return {
        "trials": len(results),
        **counts,
        "median_steps_correct": float(np.median([r.steps for r in ok])) if ok else math.nan,
        "median_pos_error_correct_m": float(np.median([r.pos_error_m for r in ok])) if ok else math.nan,
    }
