"""CARMEN log reader: the ACES log's facts (filters/robot_data/data/README.md, docs/real_robot.md) and synthetic
edge cases."""

import gzip
import math

import numpy as np
import pytest

from filters.pose import compose, relative, wrap_angle
from filters.robot_data import ACES_LOG
from filters.robot_data.carmen import CarmenLogError, flaser_angles, read_carmen

ACES = ACES_LOG


@pytest.fixture(scope="module")
def aces():
    return read_carmen(ACES)


def test_aces_counts(aces):
    assert len(aces) == 440
    assert aces.n_beams == 180
    assert aces.laser == "FLASER"
    assert aces.range_max_m == 50.0
    assert aces.odometry_convention == "anchored"
    np.testing.assert_allclose(np.degrees(aces.angles[:2]), [-90.0, -89.0])
    np.testing.assert_allclose(np.degrees(aces.angles[-1]), 89.0)
    assert aces.skipped == {"NEFF": 440}
    assert aces.params["simulator_num_readings"] == "180"
    assert len(aces.comments) == 2
    np.testing.assert_array_equal(aces.sensor_pose, [0.0, 0.0, 0.0])
    # 50.0 m readings are no-return beams
    scan = aces.scan(0)
    assert not scan.valid[scan.ranges >= 50.0].any()


def test_aces_odometry_increments(aces):
    true = relative(aces.poses[:-1], aces.poses[1:])
    err = aces.odometry[1:] - true
    pos = np.median(np.hypot(err[:, 0], err[:, 1]))
    ang = np.degrees(np.median(np.abs(wrap_angle(err[:, 2]))))
    assert 0.04 < pos < 0.06  # README: median 0.05 m
    assert 0.6 < ang < 0.8  # README: median 0.7 deg
    assert 315 < np.hypot(true[:, 0], true[:, 1]).sum() < 330  # ~323 m of travel
    np.testing.assert_array_equal(aces.odometry[0], 0.0)
    # the FLASER odom fields equal the corrected pose: the "scan" convention sees no noise at all
    scan_conv = read_carmen(ACES, odometry="scan")
    np.testing.assert_allclose(scan_conv.odometry[1:], true, atol=1e-9)


def test_aces_first_increment_by_hand(aces):
    """Scan 1: anchor = the ODOM right after scan 0, end = the last ODOM before scan 1 (lines of the file)."""
    with gzip.open(ACES, "rt") as f:
        lines = f.read().splitlines()
    i0, i1 = [i for i, s in enumerate(lines) if s.startswith("FLASER")][:2]
    odo = [i for i in range(i0 + 1, i1) if lines[i].startswith("ODOM")]
    a = np.array(lines[odo[0]].split()[1:4], float)
    b = np.array(lines[odo[-1]].split()[1:4], float)
    np.testing.assert_allclose(aces.odometry[1], relative(a, b), atol=1e-12)
    np.testing.assert_allclose(a, aces.poses[0], atol=1e-9)


def test_subset_and_dead_reckoning(aces):
    part = aces.subset(10, 20)
    assert len(part) == 10
    np.testing.assert_array_equal(part.odometry[0], 0.0)
    np.testing.assert_array_equal(part.odometry[1:], aces.odometry[11:20])
    dr = part.odometry_poses()
    np.testing.assert_allclose(dr[0], part.poses[0])
    assert np.hypot(*(dr[-1, :2] - part.poses[-1, :2])) < 2.0
    with pytest.raises(ValueError, match="subset"):
        aces.subset(5, 5)


def _flaser(ranges, pose, odom, ts):
    r = " ".join(f"{v:.3f}" for v in ranges)
    p = " ".join(f"{v:.6f}" for v in pose)
    o = " ".join(f"{v:.6f}" for v in odom)
    return f"FLASER {len(ranges)} {r} {p} {o} {ts:.4f} host {ts:.4f}"


def test_raw_log_scan_convention_and_broken_timestamps(tmp_path):
    poses = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.1), (1.5, 0.5, 0.3)]
    lines = ["# a raw log", "PARAM robot_frontlaser_offset 0.2 nohost 0", "PARAM robot_front_laser_max 8.0"]
    for k, p in enumerate(poses):
        lines.append(f"ODOM {p[0]} {p[1]} {p[2]} 0 0 0 {5 - k} host 0")
        lines.append(_flaser([1.0, 2.0, 9.0], compose(np.array(p), [0.2, 0, 0]), p, ts=5.0 - k))  # time runs back
    lines.append("TRUEPOS 1 2 3")
    f = tmp_path / "raw.log"
    f.write_text("\n".join(lines) + "\n")
    log = read_carmen(f)
    assert log.odometry_convention == "scan"
    assert log.range_max_m == 8.0
    np.testing.assert_allclose(log.sensor_pose, [0.2, 0.0, 0.0])
    np.testing.assert_allclose(log.poses, poses, atol=1e-6)  # the laser offset is removed
    np.testing.assert_allclose(log.odometry[2], relative(np.array(poses[1]), np.array(poses[2])), atol=1e-6)
    np.testing.assert_array_equal(log.timestamps, [5.0, 4.0, 3.0])  # file order kept
    assert log.skipped == {"TRUEPOS": 1}
    assert log.comments == ("a raw log",)
    assert not log.scan(0).valid[2]  # 9 m > 8 m max: no return
    np.testing.assert_allclose(log.scan(0).sensor_pose, [0.2, 0.0, 0.0])
    cont = read_carmen(f, odometry="continuous")
    np.testing.assert_allclose(cont.odometry, log.odometry, atol=1e-6)


def test_robotlaser1(tmp_path):
    def rl(ranges, laser_pose, robot_pose):
        r, lp, rp = (" ".join(map(str, v)) for v in (ranges, laser_pose, robot_pose))
        return f"ROBOTLASER1 0 -1.5708 3.14159 0.0174533 30.0 0.01 0 {len(ranges)} {r} 0 {lp} {rp} 0 0 1 1 0 7.0 h 7.0"

    robot = [np.array([0.0, 0.0, 0.0]), np.array([0.5, 0.0, math.pi / 2])]
    off = np.array([0.1, 0.05, 0.0])
    lines = [rl([1.0] * 5, compose(r, off), r) for r in robot]
    f = tmp_path / "rl.log"
    f.write_text("\n".join(lines) + "\n")
    log = read_carmen(f)
    assert log.laser == "ROBOTLASER1"
    assert log.range_max_m == 30.0
    np.testing.assert_allclose(log.sensor_pose, off, atol=1e-12)
    np.testing.assert_allclose(log.poses, robot, atol=1e-12)
    np.testing.assert_allclose(log.angles[1] - log.angles[0], 0.0174533)
    np.testing.assert_allclose(log.odometry[1], relative(robot[0], robot[1]), atol=1e-12)


@pytest.mark.parametrize(
    "line, match",
    [
        ("FLASER 3 1.0 2.0", "3 readings make 12 fields"),
        ("FLASER x 1.0", "not an integer"),
        ("FLASER 2 1.0 abc 0 0 0 0 0 0 1.0 h 1.0", "non-numeric field 'abc' at position 1 of 2"),
        (
            "FLASER 3 1.0 2.0 3.0 0 0 0 0 0 0 1.0 h 1.0",
            r"different beam counts \[2, 3\]: this one has 3, the first \(line 2\) 2",
        ),
        ("FLASER 2 1.0 -2.0 0 0 0 0 0 0 1.0 h 1.0", "negative range"),
        ("FLASER 2 1.0 2.0 3.3 0 0 0 0 0 0 1.0 h 1.0", "2 readings make 11 fields .* got 14"),  # one reading extra
        ("FLASER 3 1.0 2.0 0 0 0 0 0 0 1.0 h 1.0", "3 readings make 12 fields .* got 13"),  # one reading short
        ("FLASER 2 1.0 nan 0 0 0 0 0 0 1.0 h 1.0", "non-finite value 'nan' at position 1 of 2"),
        ("ODOM 1 2", "ODOM"),
        ("ODOM 1 0 0 0 0 2.0 h 2.0", "ODOM: x y theta tv rv accel make 8 fields .* got 9"),  # y missing
        ("ODOM 1 2 0 0 0 0 2.0 h", "got 9"),  # a line cut off at the end of a truncated file
        ("ODOM 1 2 0 0 0 0 2.0 h 2.0 7", "got 11"),
    ],
)
def test_malformed_lines(tmp_path, line, match):
    f = tmp_path / "bad.log"
    f.write_text("# ok\n" + _flaser([1.0, 2.0], (0, 0, 0), (0, 0, 0), 0.0) + "\n" + line + "\n")
    with pytest.raises(CarmenLogError, match=match) as e:
        read_carmen(f)
    assert e.value.line in (0, 3)


def test_a_last_line_cut_off_says_so(tmp_path):
    """A recorder stopped mid-write leaves a last line without its newline: the error names that cause
    (a new user's trial); a malformed line that ends in a newline gets the plain message."""
    ok = _flaser([1.0, 2.0], (0, 0, 0), (0, 0, 0), 0.0) + "\n"
    cut = _flaser([1.0, 2.0], (0, 0, 0), (0, 0, 0), 1.0)[:-9]
    (tmp_path / "cut.log").write_text(ok + cut)
    with pytest.raises(CarmenLogError, match="last line, without a newline at its end: cut off") as e:
        read_carmen(tmp_path / "cut.log")
    assert e.value.line == 2
    (tmp_path / "bad.log").write_text(ok + cut + "\n")
    with pytest.raises(CarmenLogError) as e:
        read_carmen(tmp_path / "bad.log")
    assert "cut off" not in str(e.value)


def test_robotlaser_field_count(tmp_path):
    head = "ROBOTLASER1 0 -1.5 3.1 0.01 80 0.01 0 2 1.0 2.0 0"  # 2 readings, no remissions
    tail = " 0 0 0 0 0 0 0 0 0 0 0 1.0"  # laser and robot pose, tv rv fwd side turn_axis, timestamp
    f = tmp_path / "rl.log"
    for extra, ok in (("", True), (" h 1.0", True), (" h 1.0 9", False), (" h", False)):
        f.write_text(head + tail + extra + "\n")
        if ok:
            assert read_carmen(f).ranges.shape == (1, 2)
        else:
            with pytest.raises(CarmenLogError, match="ROBOTLASER1: 2 readings and 0 remissions make 24 fields"):
                read_carmen(f)


def test_message_lengths_with_and_without_host_and_logger_timestamp(tmp_path):
    """Both documented lengths read the same (older CARMEN logs end a message at its timestamp)."""
    full = _flaser([1.0, 2.0], (0, 0, 0), (0, 0, 0), 0.0)
    short = " ".join(full.split()[:-2])
    f, g = tmp_path / "full.log", tmp_path / "short.log"
    f.write_text(f"{full}\nODOM 0.1 0 0 0 0 0 1.0 h 1.0\n{full}\n")
    g.write_text(f"{short}\nODOM 0.1 0 0 0 0 0 1.0\n{short}\n")
    a, b = read_carmen(f), read_carmen(g)
    np.testing.assert_array_equal(a.ranges, b.ranges)
    np.testing.assert_array_equal(a.odometry, b.odometry)


def test_bad_arguments(tmp_path):
    f = tmp_path / "empty.log"
    f.write_text("# nothing\nODOM 0 0 0 0 0 0 0 h 0\n")
    with pytest.raises(CarmenLogError, match="no FLASER or ROBOTLASER1"):
        read_carmen(f)
    with pytest.raises(ValueError, match="laser must be"):
        read_carmen(ACES, laser="RLASER")
    with pytest.raises(ValueError, match="odometry must be"):
        read_carmen(ACES, odometry="gps")
    with pytest.raises(ValueError, match="range_max_m"):
        read_carmen(ACES, range_max_m=-1.0)
    with pytest.raises(ValueError, match="angles must be 180"):
        read_carmen(ACES, angles=np.zeros(3))
    with pytest.raises(FileNotFoundError):
        read_carmen(tmp_path / "missing.log")
    with pytest.raises(CarmenLogError, match="no ODOM"):
        g = tmp_path / "two.log"
        g.write_text(_flaser([1.0], (0, 0, 0), (0, 0, 0), 0) + "\n" + _flaser([1.0], (1, 0, 0), (1, 0, 0), 1) + "\n")
        read_carmen(g, odometry="anchored")


def test_flaser_angles():
    np.testing.assert_allclose(np.degrees(flaser_angles(181))[[0, -1]], [-90.0, 90.0])
    np.testing.assert_allclose(np.degrees(flaser_angles(360))[[0, 1]], [-90.0, -89.5])


@pytest.mark.parametrize(
    "text, match",
    [
        ("PARAM robot_frontlaser_offset nan\n", "bad.log:1: .*robot_frontlaser_offset"),
        ("PARAM robot_frontlaser_offset 1e308\n", "robot_frontlaser_offset must be a number within"),
        ("PARAM robot_front_laser_max inf\n", "bad.log:1: .*robot_front_laser_max"),
        ("PARAM robot_front_laser_max -5\n", "bad.log:1: PARAM robot_front_laser_max must be a finite number > 0"),
        ("PARAM laser_front_laser_max 0\n", "bad.log:1: PARAM laser_front_laser_max must be a finite number > 0"),
        ("FLASER 0  0 0 0 0 0 0 1.0 host 1.0\nFLASER 0  0 0 0 0 0 0 1.0 host 1.0\n", "no range readings"),
        (
            "ROBOTLASER1 0 -1.57 3.14 1e308 8.0 0.01 0 3 1 1 1 0 0 0 0 0 0 0 0 0 0 0 0 1.0 host 1.0\n",
            "not angles",
        ),
    ],
)
def test_bad_values_are_refused_when_read_not_later(tmp_path, text, match):
    # an input audit found these accepted, failing only when a scan was built (or never)
    f = tmp_path / "bad.log"
    scan = _flaser([1.0, 2.0], (0, 0, 0), (0, 0, 0), 0.0) + "\n"
    f.write_text(text + (scan if "LASER" not in text else ""))
    with pytest.raises(CarmenLogError, match=match):
        read_carmen(f)


def test_a_corrupt_gzip_log_is_a_carmen_log_error(tmp_path):
    import gzip

    good = gzip.compress((_flaser([1.0, 2.0], (0, 0, 0), (0, 0, 0), 0.0) + "\n").encode() * 50)
    for name, data in (("cut.log.gz", good[: len(good) // 2]), ("header.log.gz", b"\x1f\x8b\x99" + good[3:])):
        f = tmp_path / name
        f.write_bytes(data)
        with pytest.raises(CarmenLogError, match="cannot read"):
            read_carmen(f)


def test_a_lone_outlier_does_not_set_the_no_return_value(tmp_path):
    # a laser reports no return as its maximum, which recurs; one corrupt 80 m reading does not
    lines = [_flaser([1.0, 50.0, 2.0 + k / 10], (k, 0, 0), (k, 0, 0), float(k)) for k in range(6)]
    lines.append(_flaser([1.0, 80.0, 2.0], (6, 0, 0), (6, 0, 0), 6.0))
    f = tmp_path / "outlier.log"
    f.write_text("\n".join(lines) + "\n")
    with pytest.warns(UserWarning, match=r"1 reading\(s\) in 1 scan\(s\) exceed 50 m.* 80 m, is on line 7"):
        log = read_carmen(f)
    assert log.range_max_m == 50.0
    assert not log.scan(6).valid[1] and not log.scan(0).valid[1] and log.scan(0).valid[0]
    assert read_carmen(f, range_max_m=100.0).scan(6).valid[1]
    # no recurring maximum (every reading within range): the largest reading, as before
    g = tmp_path / "plain.log"
    g.write_text("\n".join(_flaser([1.0 + k, 2.0], (k, 0, 0), (k, 0, 0), float(k)) for k in range(4)) + "\n")
    assert read_carmen(g).range_max_m == 4.0


def test_long_real_readings_in_many_scans_are_not_taken_for_corrupt_ones(tmp_path):
    # a review: centimetre-rounded readings made some scan maximum recur, and every longer, valid
    # reading became "no return"
    rng = np.random.default_rng(0)
    lines = []
    for k in range(300):
        far = 9.0 + rng.uniform(0, 3) if k % 25 == 0 else rng.uniform(4, 6)
        lines.append(_flaser([1.0, round(far, 2), 2.0], (k, 0, 0), (k, 0, 0), float(k)))
    f = tmp_path / "long.log"
    f.write_text("\n".join(lines) + "\n")
    log = read_carmen(f)
    assert log.range_max_m == pytest.approx(log.ranges.max())


def test_poses_too_large_for_the_frame_changes_are_refused_on_their_line(tmp_path):
    # finite logged poses whose increments overflow gave NaN odometry, found only later in predict
    f = tmp_path / "huge.log"
    f.write_text(
        _flaser([1.0, 2.0], (0, 0, 0), (0, 0, 0), 0.0) + "\n" + _flaser([1.0, 2.0], (0, 0, 0), (1e308, -1e308, 0), 1.0)
    )
    with pytest.raises(CarmenLogError, match=r"huge.log:2: FLASER odometry: coordinates .* beyond \+-1e\+09 m"):
        read_carmen(f)
    f.write_text("ODOM 0 2e9 0 0 0 0 0 host 0\n" + _flaser([1.0, 2.0], (0, 0, 0), (0, 0, 0), 0.0))
    with pytest.raises(CarmenLogError, match=r"huge.log:1: ODOM pose: coordinates \[0.0, 2000000000.0\]"):
        read_carmen(f)
