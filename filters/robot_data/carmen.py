"""Reader for CARMEN robot logs (the text format of the Radish data sets and CARMEN's logger).

One line per message, fields separated by white space:

* ``# ...``: a comment (kept in `CarmenLog.comments`).
* ``PARAM name value [host timestamp]``: a parameter (kept in `CarmenLog.params`).
* ``ODOM x y theta tv rv accel timestamp host logger_timestamp``: the odometry pose.
* ``FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta timestamp host logger_timestamp``:
  a front-laser scan; ``x y theta`` is the laser's pose, ``odom_*`` the robot's odometry pose.
  Beam angles are not in the message (see ``flaser_angles`` of `read_carmen`).
* ``ROBOTLASER1 type start_angle fov resolution max_range accuracy remission_mode n r_1 .. r_n
  n_rem rem_1 .. rem_m laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv fwd side
  turn_axis timestamp host logger_timestamp``: a scan with its geometry.
* Any other message (``RLASER``, ``TRUEPOS``, ``SYNC``, ``NEFF``, ...) is counted in
  `CarmenLog.skipped` and otherwise ignored.

An ``ODOM``, ``FLASER`` or ``ROBOTLASER1`` line must have exactly its fields as above, or end at its
``timestamp`` (older logs have no host and logger timestamp); any other count is a `CarmenLogError`
naming the line, since one field more or less would shift every later field into the wrong place.

Messages are taken in **file order**: the timestamps of many Radish logs are broken (zero,
repeated or going backwards), so they are kept (`CarmenLog.timestamps`) but never used
to sort.

Scans. Only one laser message type is read (``laser="FLASER"`` or ``"ROBOTLASER1"``; the
default ``"auto"`` takes whichever comes first in the file). The sensor's mounting pose in the
robot frame (`CarmenLog.sensor_pose`) is ``(robot_frontlaser_offset, 0, 0)`` from the
``PARAM`` lines for ``FLASER`` (0 if absent) and, for ``ROBOTLASER1``, the laser pose
relative to the robot pose of the first scan. `CarmenLog.poses` are *robot* poses: the
logged laser pose with that offset removed.

Odometry (`CarmenLog.odometry`, ``(K, 3)`` increments ``(dx, dy, dtheta)`` in the frame
of the previous scan's robot pose, as `filters.pose.relative` gives; row 0 is zero).
Three conventions, ``odometry=`` of `read_carmen`:

* ``"anchored"`` — *corrected* logs (e.g. Radish ``*-corrected.log``): the scan poses are the
  scan-matched ones, the ``odom_*`` fields equal them, and the raw odometry lives in the
  ``ODOM`` lines, re-anchored at every scan: the first ``ODOM`` after scan ``k - 1`` repeats
  its corrected pose and later ``ODOM`` lines continue from it with raw increments. The
  increment for scan ``k`` is the motion from that anchor to the last ``ODOM`` before scan ``k``.
* ``"continuous"``: ``ODOM`` lines form one raw trajectory; the increment is the motion between
  the last ``ODOM`` before scan ``k - 1`` and the last before scan ``k``.
* ``"scan"``: the odometry pose stored in each scan (``odom_*`` of ``FLASER``, ``robot_*`` of
  ``ROBOTLASER1``, raw logs).
* ``"auto"`` (default): ``"anchored"`` if the first ``ODOM`` after at least 90 % of the scans
  repeats the scan's pose (within 1e-6), else ``"scan"``.

Malformed lines raise `CarmenLogError` naming the file, the line number and the problem.
"""

from __future__ import annotations

import gzip
import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from filters.pose import compose, relative
from filters.robot_data.scans import LaserScan

__all__ = ["CarmenLog", "CarmenLogError", "read_carmen", "flaser_angles"]

_LASERS = ("FLASER", "ROBOTLASER1")
_ODOMETRY = ("auto", "anchored", "continuous", "scan")
_ANCHOR_TOL = 1e-6


class CarmenLogError(ValueError):
    """A CARMEN log line is malformed. ``path``, ``line`` (1-based) and ``problem`` say where and what."""

    def __init__(self, path: str, line: int, problem: str) -> None:
        self.path = path
        self.line = line
        self.problem = problem
        super().__init__(f"{path}:{line}: {problem}")


def flaser_angles(n: int) -> np.ndarray:
    """Default ``FLASER`` beam angles (radians, laser frame): ``-pi/2 + i * step``.

    ``step`` is ``pi / (n - 1)`` for an odd ``n`` (181 or 361 readings: both ends of a
    180 degree scan) and ``pi / n`` for an even ``n`` (180 or 360: a SICK scan without its
    last reading; for the ACES log this fits the map better than ``linspace(-90, 90, 180)``).
    """
    if n < 2:
        raise ValueError(f"flaser_angles: need at least 2 beams, got {n}")
    step = math.pi / (n - 1) if n % 2 else math.pi / n
    return -math.pi / 2 + step * np.arange(n)


@dataclass(frozen=True, eq=False)
class CarmenLog:
    """The scans of a CARMEN log, in file order, with poses and odometry increments.

    Attributes:
        path: the file read.
        laser: message type of the scans (``"FLASER"`` or ``"ROBOTLASER1"``).
        ranges: ``(K, B)`` metres (``>= range_max_m`` = no return).
        angles: ``(B,)`` beam angles in the laser frame, radians.
        range_max_m: no-return limit of every scan.
        poses: ``(K, 3)`` logged robot poses (corrected ones in a corrected log).
        odometry: ``(K, 3)`` raw odometry increments (row ``k``: from scan ``k - 1`` to ``k``;
            row 0 zero), see the module docstring.
        odometry_convention: the convention used (``"anchored"``, ``"continuous"`` or ``"scan"``).
        sensor_pose: ``(3,)`` laser pose in the robot frame.
        timestamps: ``(K,)`` the scans' logged timestamps (not used for ordering).
        line_numbers: ``(K,)`` 1-based line of each scan in the file.
        params: ``PARAM`` name -> value (string).
        comments: comment lines without the ``#``.
        skipped: message type -> count, for the lines that were ignored.
    """

    path: str
    laser: str
    ranges: np.ndarray
    angles: np.ndarray
    range_max_m: float
    poses: np.ndarray
    odometry: np.ndarray
    odometry_convention: str
    sensor_pose: np.ndarray
    timestamps: np.ndarray
    line_numbers: np.ndarray
    params: dict = field(default_factory=dict)
    comments: tuple = ()
    skipped: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.ranges.shape[0])

    @property
    def n_beams(self) -> int:
        return int(self.ranges.shape[1])

    def scan(self, k: int) -> LaserScan:
        """Scan ``k`` as a `LaserScan` (with the mounting pose)."""
        if not -len(self) <= k < len(self):
            raise IndexError(f"scan index {k} out of range for {len(self)} scans")
        return LaserScan(self.ranges[k], self.angles, self.range_max_m, sensor_pose=self.sensor_pose)

    def scans(self) -> list[LaserScan]:
        """All scans, in file order."""
        return [self.scan(k) for k in range(len(self))]

    def odometry_poses(self, start=None) -> np.ndarray:
        """``(K, 3)`` dead-reckoned poses: the increments chained from ``start`` (default ``poses[0]``)."""
        p = np.asarray(self.poses[0] if start is None else start, dtype=np.float64).reshape(3)
        out = np.empty((len(self), 3))
        for k in range(len(self)):
            p = compose(p, self.odometry[k])
            out[k] = p
        return out

    def subset(self, start: int, stop: int) -> CarmenLog:
        """Scans ``start .. stop - 1`` (odometry row of the first one set to zero)."""
        if not 0 <= start < stop <= len(self):
            raise ValueError(f"subset: need 0 <= start < stop <= {len(self)}, got {start}, {stop}")
        odo = self.odometry[start:stop].copy()
        odo[0] = 0.0
        sl = slice(start, stop)
        return CarmenLog(
            path=self.path,
            laser=self.laser,
            ranges=self.ranges[sl],
            angles=self.angles,
            range_max_m=self.range_max_m,
            poses=self.poses[sl],
            odometry=odo,
            odometry_convention=self.odometry_convention,
            sensor_pose=self.sensor_pose,
            timestamps=self.timestamps[sl],
            line_numbers=self.line_numbers[sl],
            params=dict(self.params),
            comments=self.comments,
            skipped=dict(self.skipped),
        )


def _open_text(path: Path):
    with open(path, "rb") as f:
        gz = f.read(2) == b"\x1f\x8b"
    return gzip.open(path, "rt", encoding="latin-1") if gz else open(path, encoding="latin-1")


def _is_float(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _floats(tokens: list[str], what: str, path: str, lineno: int) -> list[float]:
    try:
        vals = [float(t) for t in tokens]
    except ValueError:
        i = next(i for i, t in enumerate(tokens) if not _is_float(t))
        raise CarmenLogError(
            path, lineno, f"{what}: non-numeric field {tokens[i]!r:.40} at position {i} of {len(tokens)}"
        ) from None
    bad = [i for i, v in enumerate(vals) if not math.isfinite(v)]
    if bad:
        i = bad[0]
        raise CarmenLogError(path, lineno, f"{what}: non-finite value {tokens[i]!r} at position {i} of {len(vals)}")
    return vals


MAX_LOG_POSE_M = 1e9
"""Largest logged coordinate taken (metres): beyond, the frame changes would overflow or lose every centimetre."""


def _pose(tokens: list[str], what: str, path: str, lineno: int) -> list[float]:
    """`_floats` of a logged pose ``x y theta``, its coordinates within `MAX_LOG_POSE_M`."""
    vals = _floats(tokens, what, path, lineno)
    if any(abs(v) > MAX_LOG_POSE_M for v in vals[:2]):
        raise CarmenLogError(
            path, lineno, f"{what}: coordinates {vals[:2]} beyond +-{MAX_LOG_POSE_M:g} m (not metres?)"
        )
    return vals


def _count(tok: list[str], i: int, what: str, path: str, lineno: int) -> int:
    if i >= len(tok):
        raise CarmenLogError(path, lineno, f"{what}: line ends before the reading count")
    try:
        n = int(tok[i])
    except ValueError:
        raise CarmenLogError(path, lineno, f"{what}: reading count {tok[i]!r} is not an integer") from None
    if n < 0:
        raise CarmenLogError(path, lineno, f"{what}: negative reading count {n}")
    return n


def _check_length(tok: list[str], short: int, what: str, detail: str, path: str, lineno: int) -> None:
    """A message of ``short`` fields up to its timestamp, or ``short + 2`` with host and logger timestamp."""
    if len(tok) not in (short, short + 2):
        raise CarmenLogError(
            path,
            lineno,
            f"{what}: {detail} make {short} fields up to the timestamp ({short + 2} with host and logger "
            f"timestamp), got {len(tok)}: a field missing or extra (a reading count that does not match?)",
        )


def _parse_flaser(tok, path, lineno):
    n = _count(tok, 1, "FLASER", path, lineno)
    _check_length(tok, 2 + n + 7, "FLASER", f"{n} readings", path, lineno)
    ranges = _floats(tok[2 : 2 + n], "FLASER ranges", path, lineno)
    pose = _pose(tok[2 + n : 5 + n], "FLASER pose", path, lineno)
    odom = _pose(tok[5 + n : 8 + n], "FLASER odometry", path, lineno)
    ts = _floats(tok[8 + n : 9 + n], "FLASER timestamp", path, lineno)[0]
    return {"ranges": ranges, "laser_pose": pose, "robot_odom": odom, "timestamp": ts}


def _parse_robotlaser(tok, path, lineno):
    head = _floats(tok[2:7], "ROBOTLASER1 header", path, lineno)
    if len(head) != 5:
        raise CarmenLogError(path, lineno, "ROBOTLASER1: line ends inside the header")
    start, fov, res, max_range, _acc = head
    if not (abs(start) <= 2 * math.pi and 0 <= res <= 2 * math.pi and 0 <= fov <= 2 * math.pi):
        raise CarmenLogError(path, lineno, f"ROBOTLASER1: start {start}, fov {fov}, resolution {res} are not angles")
    n = _count(tok, 8, "ROBOTLASER1", path, lineno)
    i = 9 + n
    m = _count(tok, i, "ROBOTLASER1 remissions", path, lineno)
    i += 1 + m
    _check_length(tok, i + 12, "ROBOTLASER1", f"{n} readings and {m} remissions", path, lineno)
    ranges = _floats(tok[9 : 9 + n], "ROBOTLASER1 ranges", path, lineno)
    laser_pose = _pose(tok[i : i + 3], "ROBOTLASER1 laser pose", path, lineno)
    robot_pose = _pose(tok[i + 3 : i + 6], "ROBOTLASER1 robot pose", path, lineno)
    ts = _floats(tok[i + 11 : i + 12], "ROBOTLASER1 timestamp", path, lineno)[0]
    return {
        "ranges": ranges,
        "laser_pose": laser_pose,
        "robot_odom": robot_pose,
        "timestamp": ts,
        "geometry": (start, fov, res, max_range),
    }


MAX_LASER_OFFSET_M = 10.0
"""Largest ``PARAM robot_frontlaser_offset`` taken (metres): a laser mounted on the robot."""


def _clipped_max(ranges: np.ndarray, scans: list, spath: str) -> float:
    """The no-return limit of a log that does not state it. A laser reports no return as its maximum, so
    in a log that has any, one value is the longest reading of many scans: of at least 5 % of them (and
    of 3). If one such value exists and readings above it occur in at most 1 % of the scans (and in 1),
    it is the limit, and those readings, such as a lone corrupt one, count as no return, with a warning
    naming the first; otherwise the largest reading is."""
    longest = ranges.max(axis=1)
    n = len(longest)
    values, counts = np.unique(longest, return_counts=True)
    recurring = values[counts >= max(min(3, n), 0.05 * n)]
    if not recurring.size:
        return float(longest.max())
    limit = float(recurring.max())
    above = np.flatnonzero(longest > limit)
    if above.size > max(1, 0.01 * n):  # long readings in many scans: real ones, not corrupt outliers
        return float(longest.max())
    if above.size:
        warnings.warn(
            f"{spath}: {int((ranges > limit).sum())} reading(s) in {above.size} scan(s) exceed {limit:g} m, the "
            f"longest reading of many scans (the laser's no-return value), and count as no return; the first, "
            f"{longest[above[0]]:g} m, is on line {scans[above[0]]['line']} (pass range_max_m to choose)",
            stacklevel=3,
        )
    return limit


def read_carmen(
    path: str | os.PathLike,
    laser: str = "auto",
    odometry: str = "auto",
    range_max_m: float | None = None,
    angles: np.ndarray | None = None,
) -> CarmenLog:
    """Read a CARMEN log (plain text or gzip), see the module docstring.

    Args:
        path: the log file (``.gz`` is detected from the content).
        laser: ``"FLASER"``, ``"ROBOTLASER1"`` or ``"auto"`` (the first of them in the file).
        odometry: ``"auto"``, ``"anchored"``, ``"continuous"`` or ``"scan"``.
        range_max_m: no-return limit; default: ``PARAM robot_front_laser_max`` or
            ``laser_front_laser_max`` if present, the ``max_range`` of ``ROBOTLASER1``,
            else the laser's no-return value: the largest reading that is the longest of at least
            5 % of the scans (clipped no-return readings, e.g. 50.0 m in the ACES log, recur), if
            readings above it occur in at most 1 % of the scans (such as a lone corrupt one: they
            then count as no return, with a warning); else the largest reading.
        angles: ``(B,)`` beam angles in the laser frame (radians) overriding the default
            (`flaser_angles` for ``FLASER``, ``start + i * resolution`` for ``ROBOTLASER1``).

    Raises:
        CarmenLogError: a malformed line, no scan at all, or scans of different beam counts.
        ValueError: a bad argument (named).
    """
    if laser not in ("auto",) + _LASERS:
        raise ValueError(f"laser must be 'auto', 'FLASER' or 'ROBOTLASER1', got {laser!r}")
    if odometry not in _ODOMETRY:
        raise ValueError(f"odometry must be one of {_ODOMETRY}, got {odometry!r}")
    if range_max_m is not None and not (math.isfinite(range_max_m) and range_max_m > 0):
        raise ValueError(f"range_max_m must be a positive number, got {range_max_m!r}")
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"CARMEN log not found: {p}")
    spath = str(p)
    params: dict[str, str] = {}
    param_lines: dict[str, int] = {}  # where each PARAM was set, for error messages
    comments: list[str] = []
    skipped: dict[str, int] = {}
    scans: list[dict] = []
    odom: list[list[float]] = []  # every ODOM pose, in file order
    odom_before: list[int] = []  # per scan: count of ODOM lines before it
    chosen = None if laser == "auto" else laser
    try:
        with _open_text(p) as f:
            for lineno, line in enumerate(f, start=1):
                s = line.strip()
                if not s:
                    continue
                if s.startswith("#"):
                    comments.append(s[1:].strip())
                    continue
                tok = s.split()
                kind = tok[0]
                try:
                    if kind == "PARAM":
                        if len(tok) < 3:
                            raise CarmenLogError(spath, lineno, "PARAM: needs a name and a value")
                        params[tok[1]], param_lines[tok[1]] = tok[2], lineno
                    elif kind == "ODOM":
                        _check_length(tok, 8, "ODOM", "x y theta tv rv accel", spath, lineno)
                        odom.append(_pose(tok[1:4], "ODOM pose", spath, lineno))
                    elif kind in _LASERS and (chosen is None or kind == chosen):
                        chosen = kind
                        rec = (_parse_flaser if kind == "FLASER" else _parse_robotlaser)(tok, spath, lineno)
                        rec["line"] = lineno
                        scans.append(rec)
                        odom_before.append(len(odom))
                    else:
                        skipped[kind] = skipped.get(kind, 0) + 1
                except CarmenLogError as e:
                    if line.endswith("\n"):
                        raise
                    raise CarmenLogError(  # only a file's last line can lack its newline
                        spath,
                        lineno,
                        f"{e.problem} (the log's last line, without a newline at its end: cut off when the "
                        "recorder stopped, or malformed? Delete or fix that line to read the rest)",
                    ) from None
    except (EOFError, OSError, gzip.BadGzipFile) as e:  # truncated or corrupt .gz, unreadable file
        raise CarmenLogError(spath, 0, f"cannot read the log: {type(e).__name__}: {e}") from None
    if not scans:
        raise CarmenLogError(spath, 0, f"no {laser if laser != 'auto' else 'FLASER or ROBOTLASER1'} scan in the log")
    counts = {len(r["ranges"]) for r in scans}
    if len(counts) != 1:  # name the first scan whose count differs from the first scan's
        odd = next(r for r in scans if len(r["ranges"]) != len(scans[0]["ranges"]))
        raise CarmenLogError(
            spath,
            odd["line"],
            f"scans have different beam counts {sorted(counts)}: this one has {len(odd['ranges'])}, "
            f"the first (line {scans[0]['line']}) {len(scans[0]['ranges'])}",
        )
    n_beams = counts.pop()
    if n_beams == 0:
        raise CarmenLogError(spath, scans[0]["line"], "scans have no range readings")
    ranges = np.array([r["ranges"] for r in scans], dtype=np.float64).reshape(len(scans), n_beams)
    if np.any(ranges < 0):
        k = int(np.flatnonzero((ranges < 0).any(axis=1))[0])
        raise CarmenLogError(spath, scans[k]["line"], "negative range reading")
    laser_poses = np.array([r["laser_pose"] for r in scans])
    robot_odom = np.array([r["robot_odom"] for r in scans])

    # geometry
    if chosen == "FLASER":
        raw, line = params.get("robot_frontlaser_offset", "0"), param_lines.get("robot_frontlaser_offset", 0)
        try:
            off_x = float(raw)
        except ValueError:
            off_x = math.nan
        if not (math.isfinite(off_x) and abs(off_x) <= MAX_LASER_OFFSET_M):
            raise CarmenLogError(
                spath,
                line,
                f"PARAM robot_frontlaser_offset must be a number within +-{MAX_LASER_OFFSET_M:g} m, got {raw}",
            )
        sensor_pose = np.array([off_x, 0.0, 0.0])
        default_angles = flaser_angles(n_beams) if n_beams >= 2 else np.zeros(n_beams)
        geom_max = None
        for key in ("robot_front_laser_max", "laser_front_laser_max"):
            if key in params:
                raw, line = params[key], param_lines[key]
                try:
                    geom_max = float(raw)
                except ValueError:
                    geom_max = math.nan
                if not (math.isfinite(geom_max) and geom_max > 0):
                    raise CarmenLogError(spath, line, f"PARAM {key} must be a finite number > 0 (metres), got {raw}")
    else:
        start, _fov, res, geom_max = scans[0]["geometry"]
        sensor_pose = relative(robot_odom[0], laser_poses[0])
        default_angles = start + res * np.arange(n_beams)
    if angles is not None:
        a = np.asarray(angles, dtype=np.float64).reshape(-1)
        if a.shape != (n_beams,) or not np.all(np.isfinite(a)):
            raise ValueError(f"angles must be {n_beams} finite numbers (the scans' beam count), got shape {a.shape}")
        beam_angles = a
    else:
        beam_angles = default_angles
    if range_max_m is None:
        range_max_m = geom_max if geom_max is not None and geom_max > 0 else _clipped_max(ranges, scans, spath)
    if not range_max_m > 0:
        raise CarmenLogError(spath, 0, "cannot tell the laser's maximum range (all readings 0): pass range_max_m")
    robot_poses = compose(laser_poses, relative(sensor_pose, np.zeros(3)))

    # odometry
    odom_arr = np.array(odom, dtype=np.float64).reshape(-1, 3)
    nb = np.array(odom_before)
    k_all = len(scans)

    def anchor_ok(k: int) -> bool:
        i = nb[k]
        end = nb[k + 1] if k + 1 < k_all else len(odom_arr)
        if i >= end:
            return False
        d = relative(laser_poses[k], odom_arr[i])  # the anchor repeats the logged (robot) pose
        return bool(np.all(np.abs(d) < _ANCHOR_TOL)) or bool(
            np.all(np.abs(relative(robot_poses[k], odom_arr[i])) < _ANCHOR_TOL)
        )

    convention = odometry
    if convention == "auto":
        hits = sum(anchor_ok(k) for k in range(k_all))
        convention = "anchored" if hits >= 0.9 * k_all else "scan"
    inc = np.zeros((k_all, 3))
    if convention == "scan":
        inc[1:] = relative(robot_odom[:-1], robot_odom[1:])
    else:
        for k in range(1, k_all):
            last = nb[k] - 1
            ref = nb[k - 1] if convention == "anchored" else nb[k - 1] - 1
            if last < 0 or ref < 0 or ref > last:
                if convention == "anchored":
                    raise CarmenLogError(
                        spath, scans[k]["line"], "odometry='anchored': no ODOM line between this scan and the previous"
                    )
                continue  # no ODOM yet: no motion known
            inc[k] = relative(odom_arr[ref], odom_arr[last])
    for arr in (ranges, beam_angles, robot_poses, inc, sensor_pose):
        arr.setflags(write=False)
    ts = np.array([r["timestamp"] for r in scans])
    lines = np.array([r["line"] for r in scans], dtype=np.int64)
    ts.setflags(write=False)
    lines.setflags(write=False)
    return CarmenLog(
        path=spath,
        laser=chosen,
        ranges=ranges,
        angles=beam_angles,
        range_max_m=float(range_max_m),
        poses=robot_poses,
        odometry=inc,
        odometry_convention=convention,
        sensor_pose=sensor_pose,
        timestamps=ts,
        line_numbers=lines,
        params=params,
        comments=tuple(comments),
        skipped=skipped,
    )
