"""The Python bindings against known answers: simulated buildings with
ground truth, a bit-identical save and load, and a real scenario that must
give the CLI's estimates scan by scan."""
import copy
import copyreg
import csv
import json
import math
import os
import pathlib
import pickle
import shutil
import struct
import subprocess
import threading
import warnings

import numpy as np
import pytest

import lshloc

ROOT = pathlib.Path(__file__).resolve().parents[2]
DATA = pathlib.Path(os.environ.get("LSHLOC_DATA", pathlib.Path(__file__).resolve().parents[3] / "shared" / "data"))


def find_cli(environ=os.environ, root=ROOT):
    """The lshloc command: LSHLOC_CLI when set, else `lshloc` on PATH, else <repo>/build/bin/lshloc when
    built; None when there is none (pytest run by hand, without ctest)."""
    if environ.get("LSHLOC_CLI"):
        return environ["LSHLOC_CLI"]
    built = root / "build" / "bin" / "lshloc"
    return shutil.which("lshloc", path=environ.get("PATH", os.defpath)) or (str(built) if built.is_file() else None)


@pytest.fixture(scope="session")
def cli():
    """The lshloc command; the tests that run it skip when there is none."""
    found = find_cli()
    if found is None:
        pytest.skip("no lshloc command: set LSHLOC_CLI, put lshloc on PATH or build <repo>/build/bin/lshloc")
    if shutil.which(found) is None:  # named by LSHLOC_CLI, so a mistake to report, not a reason to skip
        pytest.fail(f"LSHLOC_CLI={found}: no such executable")
    return found


def feed(gmap, submaps):
    """One scan of each submap in turn, as `lshloc localize` feeds its map logs."""
    ids = [gmap.add_submap(name) for name, _ in submaps]
    for i in range(max(len(scans) for _, scans in submaps)):
        for sid, (_, scans) in zip(ids, submaps):
            if i < len(scans):
                gmap.add_scan(sid, scans[i], scans[i].pose)


@pytest.fixture(scope="module")
def world(tmp_path_factory, cli):
    d = tmp_path_factory.mktemp("sim")
    subprocess.run([cli, "simulate", "--out", str(d), "--buildings", "2", "--seed", "3", "--scans", "1200"],
                   check=True, capture_output=True)
    return d


def assert_localizes_in_b(gmap, target, b):
    """Scans 300..449 of the target touring building b end confident in submap "b", within 0.3 m of the truth."""
    loc = lshloc.Localizer(gmap, laser_offset=target.laser_offset)
    for scan in target.scans[300:450]:
        e = loc.add_scan(scan)
    assert e["localized"] and e["submap_name"] == "b"
    # The target's truth: b's corrected log holds the true laser pose of the same scan.
    truth = b.scans[449].pose
    assert math.hypot(e["pose"][0] - truth[0], e["pose"][1] - truth[1]) < 0.3


def test_a_scan_is_numpy_in_and_out():
    ranges = np.array([1.0, 2.0, np.nan, 4.0], dtype=np.float32)
    scan = lshloc.LaserScan(ranges, angle_min=-0.5, angle_increment=0.25, pose=(1.0, 2.0, 0.5))
    assert np.array_equal(scan.ranges[[0, 1, 3]], ranges[[0, 1, 3]]) and np.isnan(scan.ranges[2])
    assert np.allclose(scan.angles, [-0.5, -0.25, 0.0, 0.25])
    assert scan.pose == (1.0, 2.0, 0.5)
    with pytest.raises(lshloc.Error):
        lshloc.LaserScan(np.zeros((2, 2), dtype=np.float32), 0.0, 0.1)
    # Degrees, a non-finite geometry or pose and a NaN maximum range are refused with what was expected.
    with pytest.raises(lshloc.Error, match="expected radians"):
        lshloc.LaserScan(np.ones(181, dtype=np.float32), angle_min=-90.0, angle_increment=1.0)
    with pytest.raises(lshloc.Error, match="expected finite pose"):
        lshloc.LaserScan(ranges, angle_min=-0.5, angle_increment=0.25, pose=(np.nan, 0.0, 0.0))
    with pytest.raises(lshloc.Error, match="max_range|maximum range"):
        lshloc.LaserScan(ranges, angle_min=-0.5, angle_increment=0.25, max_range=np.nan)


def test_a_logs_warnings_reach_python(tmp_path):
    log = tmp_path / "back.log"
    line = "FLASER 3 1.0 1.0 1.0 0 0 0 0 0 0 {t} host {t}\n"
    log.write_text(line.format(t=5.0) + line.format(t=4.0))
    read = lshloc.read_carmen_log(str(log))
    assert [s.timestamp for s in read.scans] == [5.0, 4.0]
    assert len(read.warnings) == 1 and "first at line 2" in read.warnings[0], read.warnings


def test_a_log_is_a_sequence_of_scans_and_paths_may_be_pathlib(world, tmp_path):
    log = lshloc.read_carmen_log(world / "sim-3-000" / "sim-3-000-corrected.log.gz")  # a pathlib.Path
    scans = log.scans
    assert len(log) == len(scans) > 0
    assert log[0].timestamp == scans[0].timestamp and log[-1].timestamp == scans[-1].timestamp
    assert [s.timestamp for s in log] == [s.timestamp for s in scans]
    with pytest.raises(IndexError):
        log[len(log)]
    assert f"{len(log)} scans" in repr(log) and f"{len(scans[0])} beams" in repr(scans[0])
    # lshloc marks its corrected logs; the raw log's poses are odometry
    assert log.poses_corrected and not log.gmapping_corrected and "corrected poses" in repr(log)
    assert not lshloc.read_carmen_log(world / "sim-3-000" / "sim-3-000.log.gz").poses_corrected
    gmap = lshloc.GlobalMap()
    feed(gmap, [("a", scans[:100])])
    st = gmap.stats()
    assert repr(gmap) == f"<lshloc.GlobalMap: 1 submaps, 100 scans, {st['features']} features>"
    gmap.save(tmp_path / "a.map")
    assert repr(lshloc.load_map(tmp_path / "a.map")) == repr(gmap)
    grid = lshloc.occupancy_grid_from_scans(scans[:100], 0.1)
    assert f"{grid.cells.shape[1]} x {grid.cells.shape[0]} cells of 0.1 m" in repr(grid)
    lshloc.write_ros_map(tmp_path / "g", grid)
    assert lshloc.read_ros_map(tmp_path / "g.yaml").cells.shape == grid.cells.shape
    assert lshloc.__version__.count(".") == 2


def test_a_localizer_reports_its_costs_and_the_settings_it_runs_with(world):
    target = lshloc.read_carmen_log(world / "sim-3-001" / "sim-3-001.log.gz")
    gmap = lshloc.GlobalMap('{"context_spacing": 0.5}')
    feed(gmap, [("b", lshloc.read_carmen_log(world / "sim-3-001" / "sim-3-001-corrected.log.gz").scans[:200])])
    loc = lshloc.Localizer(gmap, '{"candidates_per_feature": 40}', laser_offset=(0.1, 0.0, 0.0))
    for scan in target.scans[:20]:
        loc.add_scan(scan)
    st = loc.stats()
    assert st["scans"] == 20 and st["features"] > 0 and st["hypotheses"] > 0 and st["ransac_s"] > 0.0
    settings = json.loads(loc.config_json())
    assert settings["candidates_per_feature"] == 40  # asked
    assert settings["context_spacing"] == 0.5  # the map's
    assert settings["scan_matcher"]["laser_offset"]["x"] == 0.1  # the mount


def test_localizes_in_the_right_building_against_ground_truth(world):
    a = lshloc.read_carmen_log(str(world / "sim-3-000" / "sim-3-000-corrected.log.gz"))
    b = lshloc.read_carmen_log(str(world / "sim-3-001" / "sim-3-001-corrected.log.gz"))
    target = lshloc.read_carmen_log(str(world / "sim-3-001" / "sim-3-001.log.gz"))
    gmap = lshloc.GlobalMap()
    feed(gmap, [("a", a.scans), ("b", b.scans)])
    assert gmap.submap_count == 2 and gmap.stats()["features"] > 1000
    assert_localizes_in_b(gmap, target, b)


def test_a_saved_map_loads_to_the_same_estimates(world, tmp_path):
    a = lshloc.read_carmen_log(str(world / "sim-3-000" / "sim-3-000-corrected.log.gz"))
    target = lshloc.read_carmen_log(str(world / "sim-3-000" / "sim-3-000.log.gz"))
    gmap = lshloc.GlobalMap()
    feed(gmap, [("a", a.scans)])
    gmap.save(str(tmp_path / "a.map"))
    loaded = lshloc.load_map(str(tmp_path / "a.map"))
    assert loaded.stats()["features"] == gmap.stats()["features"]
    one, two = lshloc.Localizer(gmap), lshloc.Localizer(loaded)
    for scan in target.scans[100:160]:
        assert one.add_scan(scan) == two.add_scan(scan)
    (tmp_path / "bad.map").write_bytes(b"not a map at all")
    with pytest.raises(lshloc.Error, match="not an lshloc map"):
        lshloc.load_map(str(tmp_path / "bad.map"))


def test_a_loaded_map_takes_query_settings_as_a_map_built_with_them(world, tmp_path):
    """A map saved with the defaults and given a larger candidate budget answers as one built with it;
    settings that are part of the map's contents are refused."""
    a = lshloc.read_carmen_log(str(world / "sim-3-000" / "sim-3-000-corrected.log.gz"))
    target = lshloc.read_carmen_log(str(world / "sim-3-000" / "sim-3-000.log.gz"))
    plain, built = lshloc.GlobalMap(), lshloc.GlobalMap('{"database": {"max_candidates": 1500}}')
    feed(plain, [("a", a.scans)])
    feed(built, [("a", a.scans)])
    plain.save(str(tmp_path / "plain.map"))
    loaded = lshloc.load_map(str(tmp_path / "plain.map"))
    before = lshloc.Localizer(loaded)  # made before the change: takes it from its next scan
    loaded.set_query_settings({"max_candidates": 1500})  # a dict: as its JSON text, which `built` was given
    after, reference, untouched = lshloc.Localizer(loaded), lshloc.Localizer(built), lshloc.Localizer(plain)
    differs = False
    for scan in target.scans[100:160]:
        want = reference.add_scan(scan)
        assert before.add_scan(scan) == want
        assert after.add_scan(scan) == want
        differs = differs or untouched.add_scan(scan) != want
    assert differs, "the budget changed nothing: no test"
    with pytest.raises(lshloc.Error, match="takes only max_candidates"):
        loaded.set_query_settings('{"K": 11}')
    with pytest.raises(lshloc.Error, match="max_candidates"):
        loaded.set_query_settings('{"max_candidates": 0}')


def test_a_map_from_ros_grids_localizes_against_ground_truth(world, tmp_path):
    a = lshloc.read_carmen_log(str(world / "sim-3-000" / "sim-3-000-corrected.log.gz"))
    b = lshloc.read_carmen_log(str(world / "sim-3-001" / "sim-3-001-corrected.log.gz"))
    target = lshloc.read_carmen_log(str(world / "sim-3-001" / "sim-3-001.log.gz"))
    gmap = lshloc.GlobalMap()
    first = target.scans[0]
    for name, log in (("a", a), ("b", b)):
        grid = lshloc.occupancy_grid_from_scans(log.scans)
        lshloc.write_ros_map(str(tmp_path / name), grid)
        back = lshloc.read_ros_map(str(tmp_path / (name + ".yaml")))
        assert np.array_equal(back.cells, grid.cells) and back.origin == pytest.approx(grid.origin)
        assert set(np.unique(back.cells)) <= {-1, 0, 100}
        sid, stats = gmap.add_grid_submap(name, back, beams=len(first.ranges),
                                          field_of_view=first.angles[-1] - first.angles[0])
        assert stats["virtual_scans"] == 8 * stats["positions"] and stats["features"] > 100
    assert_localizes_in_b(gmap, target, b)
    with pytest.raises(lshloc.Error, match="expected the key 'image'"):
        (tmp_path / "bad.yaml").write_text("resolution: 0.05\norigin: [0, 0, 0]\n")
        lshloc.read_ros_map(str(tmp_path / "bad.yaml"))


def test_a_map_written_on_one_thread_while_another_localizes_ends_as_one_fed_alone(world):
    """Writes take the map's lock exclusively, localizing shared: no crash, no
    spurious error, and the map ends as the same scans fed on one thread."""
    a = lshloc.read_carmen_log(str(world / "sim-3-000" / "sim-3-000-corrected.log.gz"))
    target = lshloc.read_carmen_log(str(world / "sim-3-000" / "sim-3-000.log.gz"))
    shared, alone = lshloc.GlobalMap(), lshloc.GlobalMap()
    for g in (shared, alone):
        g.add_submap("a")
        for scan in a.scans[:100]:
            g.add_scan(0, scan, scan.pose)
    errors = []

    def write():
        try:
            for scan in a.scans[100:500]:
                shared.add_scan(0, scan, scan.pose)
        except Exception as e:  # noqa: BLE001 (reported below)
            errors.append(e)

    def localize():
        try:
            loc = lshloc.Localizer(shared)
            for scan in target.scans[100:250]:
                loc.add_scan(scan)
        except Exception as e:  # noqa: BLE001
            errors.append(e)

    threads = [threading.Thread(target=write), threading.Thread(target=localize)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    for scan in a.scans[100:500]:
        alone.add_scan(0, scan, scan.pose)
    assert shared.stats() == alone.stats() and shared.submap_scans(0) == 500


def test_bad_arguments_raise_what_was_expected(world, tmp_path):
    gmap = lshloc.GlobalMap()
    with pytest.raises(TypeError):
        lshloc.Localizer(None)
    with pytest.raises(lshloc.Error, match="config_json"):
        lshloc.GlobalMap('{"database": ')
    with pytest.raises(lshloc.Error, match="features"):
        lshloc.Localizer(gmap, '{"features": {"max_keypoints": 5}}')
    with pytest.raises(lshloc.Error, match="no submap 7"):
        gmap.submap_name(7)
    scan = lshloc.LaserScan(np.ones(181, dtype=np.float32), -math.pi / 2, math.pi / 180)
    with pytest.raises(lshloc.Error, match="angle_increment"):
        lshloc.LaserScan(np.ones(181, dtype=np.float32), -math.pi / 2, 0.0)
    with pytest.raises(lshloc.Error, match="timestamp"):
        lshloc.LaserScan(np.ones(181, dtype=np.float32), -math.pi / 2, math.pi / 180, timestamp=math.nan)
    with pytest.raises(lshloc.Error, match="odometry"):
        lshloc.LaserScan(np.ones(181, dtype=np.float32), -math.pi / 2, math.pi / 180, odometry=(0.0, math.inf, 0.0))
    gmap.add_submap("a")
    with pytest.raises(lshloc.Error, match="finite pose"):
        gmap.add_scan(0, scan, (math.nan, 0.0, 0.0))
    with pytest.raises(lshloc.Error, match="max_range"):
        scan.max_range = math.nan
    with pytest.raises(lshloc.Error, match="pose"):
        scan.pose = (0.0, math.inf, 0.0)
    assert gmap.stats()["scans"] == 0
    # Occupancy cells as nav_msgs holds them: -1, 0..100; a uint8 view's 255 is -1; nothing else.
    cells = np.array([[0, 100, -1], [0, 0, 50]], dtype=np.int8)
    assert np.array_equal(lshloc.OccupancyGrid(cells, 0.05).cells, [[0, 100, -1], [0, 0, -1]])
    assert np.array_equal(lshloc.OccupancyGrid(cells.view(np.uint8), 0.05).cells, [[0, 100, -1], [0, 0, -1]])
    with pytest.raises(lshloc.Error, match="row 0, column 1\\) is 356"):
        lshloc.OccupancyGrid(np.array([[0, 356]], dtype=np.int32), 0.05)
    with pytest.raises(lshloc.Error, match="integers"):
        lshloc.OccupancyGrid(np.array([[0.0, 0.65]]), 0.05)
    with pytest.raises(lshloc.Error, match="origin"):
        lshloc.OccupancyGrid(cells, 0.05, (math.nan, 0.0, 0.0))
    with pytest.raises(lshloc.Error, match="empty"):
        lshloc.OccupancyGrid(np.zeros((0, 3), dtype=np.int8), 0.05)
    # A grid or setting that cannot make a submap leaves the map as it was.
    walls = lshloc.OccupancyGrid(np.full((20, 20), 100, dtype=np.int8), 0.05)
    room = lshloc.OccupancyGrid(np.pad(np.zeros((60, 60), dtype=np.int8), 1, constant_values=100), 0.05)
    for grid, kwargs in ((walls, {}), (room, {"headings": 0}), (room, {"pose_spacing": -1.0})):
        with pytest.raises(lshloc.Error):
            gmap.add_grid_submap("walls", grid, **kwargs)
    assert gmap.submap_count == 1


def test_a_missing_file_is_an_oserror_and_an_lshloc_error(tmp_path):
    for read in (lshloc.read_carmen_log, lshloc.load_map, lshloc.read_ros_map):
        with pytest.raises(OSError, match="missing.x: (no such file|cannot open)"):
            read(str(tmp_path / "missing.x"))
        with pytest.raises(lshloc.Error):
            read(str(tmp_path / "missing.x"))
    # A file that cannot be written is an OSError too (a missing directory, a full disk).
    with pytest.raises(OSError, match="no/such/dir/x.map"):
        lshloc.GlobalMap().save(tmp_path / "no" / "such" / "dir" / "x.map")
    with pytest.raises(OSError, match="no/such/dir/g"):
        lshloc.write_ros_map(tmp_path / "no" / "such" / "dir" / "g", lshloc.OccupancyGrid(np.zeros((2, 2), np.int8), 0.1))
    (tmp_path / "bad.log").write_text("no log here\n")
    with pytest.raises(lshloc.Error) as bad:
        lshloc.read_carmen_log(str(tmp_path / "bad.log"))
    assert not isinstance(bad.value, OSError)


def test_a_torn_journal_record_is_a_warning(world, tmp_path, cli):
    a = str(world / "sim-3-000" / "sim-3-000-corrected.log.gz")
    path = tmp_path / "m.map"
    subprocess.run([cli, "map", "build", a, "--out", str(path)], check=True, capture_output=True)
    subprocess.run([cli, "map", "append", str(path), a, "--submap", "more", "--count", "5"], check=True,
                   capture_output=True)
    with open(path, "r+b") as f:
        f.truncate(path.stat().st_size - 7)  # the last record loses its end, as a crash mid-write leaves it
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gmap = lshloc.load_map(str(path))
    assert any("torn" in str(w.message) for w in caught), [str(w.message) for w in caught]
    assert gmap.submap_scans(gmap.submap_count - 1) == 4


@pytest.mark.skipif(not (DATA / "intel").is_dir(), reason="shared data directory not found (set LSHLOC_DATA)")
def test_a_real_scenario_gives_the_cli_estimates(tmp_path, cli):
    maps = [DATA / "intel" / "intel.gfs.log.gz", DATA / "aces" / "aces-corrected.log.gz"]
    target_path = DATA / "intel" / "intel.recon-from-bag.log.gz"
    out = tmp_path / "t.tum"
    args = [cli, "localize", "--target", str(target_path), "--start", "5000", "--length", "200", "--out", str(out)]
    for m in maps:
        args += ["--map", str(m)]
    subprocess.run(args, check=True, capture_output=True)
    rows = list(csv.DictReader(open(str(out) + ".csv")))
    tum = {round(float(l.split()[0]), 6): tuple(map(float, l.split()[1:3])) for l in open(out) if l[0] != "#"}

    gmap = lshloc.GlobalMap()
    feed(gmap, [(m.name, lshloc.read_carmen_log(str(m)).scans) for m in maps])
    target = lshloc.read_carmen_log(str(target_path))
    loc = lshloc.Localizer(gmap, laser_offset=target.laser_offset)
    assert len(rows) == 200
    for row, scan in zip(rows, target.scans[5000:5200]):
        e = loc.add_scan(scan)
        # The flag is the same; a file run also marks a stamp clash with a
        # later scan, which a stream cannot see yet.
        assert (row["localized"] == "1") == e["localized"]
        assert (row["confident"] == "1") == (e["localized"] and row["stamp_clash"] == "0")
        assert row["stamp_clash"] == "1" or not e["stamp_clash"]
        assert e["confident"] == (e["localized"] and not e["stamp_clash"])
        if e["has_estimate"]:
            assert row["submap"] == e["submap_name"]
            assert row["x"] == f"{e['pose'][0]:.4f}" and row["y"] == f"{e['pose'][1]:.4f}"
            assert row["heading_deg"] == f"{math.degrees(e['pose'][2]):.3f}"
            # The same reasons keep the flag down, none while it is up.
            assert row["flag_down_because"] == ";".join(e["not_confident_because"])
            assert (e["not_confident_because"] == []) == e["localized"]
            # The robot pose is the TUM file's (the CLI takes the same mount off).
            if row["confident"] == "1" and row["submap"] == rows[-1]["submap"]:
                x, y, _ = e["robot_pose"]
                assert tum[round(scan.timestamp, 6)][:2] == pytest.approx((x, y), abs=2e-6)
    assert e["localized"] and e["submap_name"] == "intel.gfs.log.gz"


def exact(value):
    """`value` with each float as its IEEE bytes (-0.0 and NaN payloads told apart), arrays as dtype,
    shape and bytes: equal exactly when bit for bit equal."""
    if isinstance(value, (tuple, list)):
        return tuple(exact(v) for v in value)
    if isinstance(value, np.ndarray):
        return value.dtype.str, value.shape, value.tobytes()
    if isinstance(value, float):
        return struct.pack("<d", value)
    return value


def scan_fields(scan):
    # The state holds source_line, which has no property.
    return exact((scan.ranges, scan.angles, scan.angle_min, scan.angle_increment, scan.max_range, scan.timestamp,
                  scan.pose, scan.odometry, len(scan), scan.__getstate__()))


def grid_fields(grid):
    return exact((grid.cells, grid.resolution, grid.origin, grid.__getstate__()))


def test_scans_and_grids_pickle_and_copy_bit_for_bit(tmp_path):
    log = tmp_path / "two.log"
    log.write_text("FLASER 4 1.5 -1 81.0 2.25 1.0 2.0 0.5 0.9 1.9 0.4 5.0 host 5.0\n"
                   "FLASER 4 1.0 1.0 1.0 1.0 0 0 0 0 0 0 6.0 host 6.0\n")
    read = lshloc.read_carmen_log(str(log))[1]
    assert read.__getstate__()[8] == 2  # its line in the log
    payload_nan = np.uint32(0x7FC00123).view(np.float32)
    made = lshloc.LaserScan(np.array([0.5, payload_nan, np.inf, -0.0, 80.0], dtype=np.float32), angle_min=1.25,
                            angle_increment=-0.1, max_range=30.0, timestamp=1234567890.123456,
                            pose=(1e-300, -0.0, math.pi), odometry=(3.0, -4.0, -math.pi / 3))
    assert made.__getstate__()[0] == 1 and len(made.__getstate__()) == 9
    for scan in (read, made):
        for twin in (pickle.loads(pickle.dumps(scan)), copy.copy(scan), copy.deepcopy(scan)):
            assert type(twin) is lshloc.LaserScan and twin is not scan
            assert scan_fields(twin) == scan_fields(scan)
            assert np.array_equal(twin.ranges, scan.ranges, equal_nan=True)
    twin = pickle.loads(pickle.dumps(made, protocol=pickle.HIGHEST_PROTOCOL))
    assert twin.ranges[2] == np.inf and twin.ranges.view(np.uint32)[1] == 0x7FC00123
    assert math.copysign(1.0, twin.pose[1]) == -1.0
    twin.timestamp = 7.0  # a copy, not a view of the original
    assert made.timestamp == 1234567890.123456

    cells = np.array([[0, 100, -1], [-1, 0, 100]], dtype=np.int8)
    grid = lshloc.OccupancyGrid(cells, 0.05, (-1.5, 2.25, 0.3))
    state = grid.__getstate__()
    assert state[0] == 1 and np.array_equal(state[1], cells) and state[2:] == (0.05, (-1.5, 2.25, 0.3), 3, 2)
    for twin in (pickle.loads(pickle.dumps(grid)), copy.copy(grid), copy.deepcopy(grid)):
        assert type(twin) is lshloc.OccupancyGrid and twin is not grid
        assert grid_fields(twin) == grid_fields(grid)


def test_a_bad_pickle_state_is_refused_saying_what_was_expected():
    scan = lshloc.LaserScan(np.ones(3, np.float32), 0.0, 0.1)
    state = scan.__getstate__()

    class Future:
        """Pickles as a LaserScan of a state version this lshloc does not know."""

        def __reduce__(self):
            return copyreg.__newobj__, (lshloc.LaserScan,), (2,) + state[1:]

    with pytest.raises(lshloc.Error, match=r"unknown state version 2 .*expected a state tuple \(1, ranges, "):
        pickle.loads(pickle.dumps(Future(), protocol=1))  # (2 and up insist that Future is a LaserScan)

    def restore(cls, bad):
        cls.__new__(cls).__setstate__(bad)

    with pytest.raises(lshloc.Error, match="got 8 items instead of 9"):
        restore(lshloc.LaserScan, state[:-1])
    with pytest.raises(lshloc.Error, match=r"expected a state tuple \(1, ranges, .*\), got list"):
        restore(lshloc.LaserScan, list(state))
    with pytest.raises(lshloc.Error, match="the version, an int, first"):
        restore(lshloc.LaserScan, ("1",) + state[1:])
    with pytest.raises(lshloc.Error, match=r"item 5 \(timestamp\) is 'noon'"):
        restore(lshloc.LaserScan, state[:5] + ("noon",) + state[6:])
    with pytest.raises(lshloc.Error, match="finite timestamp"):  # the constructor's checks hold too
        restore(lshloc.LaserScan, state[:5] + (math.nan,) + state[6:])
    grid_state = lshloc.OccupancyGrid(np.zeros((2, 3), np.int8), 0.05).__getstate__()
    with pytest.raises(lshloc.Error, match=r"unknown state version 0 .*\(1, cells, resolution, origin, width, "):
        restore(lshloc.OccupancyGrid, (0,) + grid_state[1:])
    with pytest.raises(lshloc.Error, match="width 2 and height 3 disagree with the cells' 2 rows of 3"):
        restore(lshloc.OccupancyGrid, grid_state[:4] + (2, 3))


def test_arrays_are_read_only_copies():
    ranges = np.array([1.0, 2.5, np.nan, 4.0], dtype=np.float32)
    scan = lshloc.LaserScan(ranges, angle_min=-0.5, angle_increment=0.25)
    for array in (scan.ranges, scan.angles):
        assert not array.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 7
    assert np.array_equal(scan.ranges, ranges, equal_nan=True) and scan.angles.tolist() == [-0.5, -0.25, 0.0, 0.25]
    ranges[1] = 9.0  # the scan holds its own copy
    assert scan.ranges[1] == 2.5
    changed = scan.ranges.copy()  # other ranges: a new scan from a writable copy
    changed[0] = 7.0
    assert lshloc.LaserScan(changed, scan.angle_min, scan.angle_increment).ranges[0] == 7.0 and scan.ranges[0] == 1.0
    cells = np.array([[0, 100], [-1, 0]], dtype=np.int8)
    grid = lshloc.OccupancyGrid(cells, 0.05)
    with pytest.raises(ValueError, match="read-only"):
        grid.cells[0, 0] = 100
    assert np.array_equal(grid.cells, cells)


def test_config_json_may_be_a_dict():
    map_settings = {"context_spacing": 0.5, "features": {"max_keypoints": 12}}
    settings = {"candidates_per_feature": 40, "ransac": {"seed": 7}}
    by_dict = lshloc.Localizer(lshloc.GlobalMap(map_settings), settings, laser_offset=(0.1, 0.0, 0.0))
    by_text = lshloc.Localizer(lshloc.GlobalMap(json.dumps(map_settings)), json.dumps(settings),
                               laser_offset=(0.1, 0.0, 0.0))
    assert by_dict.config_json() == by_text.config_json()
    runs = json.loads(by_dict.config_json())
    assert runs["context_spacing"] == 0.5 and runs["features"]["max_keypoints"] == 12  # the map's
    assert runs["candidates_per_feature"] == 40 and runs["ransac"]["seed"] == 7  # the localizer's
    with pytest.raises(lshloc.Error, match=r"config_json: database\.Lx: unknown setting"):
        lshloc.GlobalMap({"database": {"Lx": 16}})
    with pytest.raises(lshloc.Error, match=r"config_json: ransac\.sed: unknown setting"):
        lshloc.Localizer(lshloc.GlobalMap(), {"ransac": {"sed": 7}})
    with pytest.raises(lshloc.Error, match="takes only max_candidates"):
        lshloc.GlobalMap().set_query_settings({"K": 11})
    with pytest.raises(lshloc.Error, match="json.dumps says: Out of range float"):  # JSON has no NaN
        lshloc.GlobalMap({"context_spacing": math.nan})
    with pytest.raises(TypeError):
        lshloc.GlobalMap(["context_spacing", 0.5])


def test_a_map_lists_its_submap_names_in_id_order(tmp_path):
    gmap = lshloc.GlobalMap()
    assert gmap.submap_names == []
    assert [gmap.add_submap("west wing"), gmap.add_submap("annex")] == [0, 1]
    assert gmap.submap_names == ["west wing", "annex"] == [gmap.submap_name(i) for i in range(gmap.submap_count)]
    gmap.submap_names.append("x")  # a new list on each access
    assert gmap.submap_names == ["west wing", "annex"]
    with pytest.raises(AttributeError):
        gmap.submap_names = ["a", "b"]
    gmap.save(tmp_path / "m.map")
    assert lshloc.load_map(tmp_path / "m.map").submap_names == ["west wing", "annex"]


def test_a_map_from_sources_is_the_map_the_cli_builds(world, tmp_path, cli):
    a = world / "sim-3-000" / "sim-3-000-corrected.log.gz"
    b = world / "sim-3-001" / "sim-3-001-corrected.log.gz"
    gmap = lshloc.map_from_sources([str(a), str(b)])
    assert gmap.submap_names == ["sim-3-000-corrected.log.gz", "sim-3-001-corrected.log.gz"]
    subprocess.run([cli, "map", "build", "--out", str(tmp_path / "ab.map"), str(a), str(b)], check=True,
                   capture_output=True)
    built = lshloc.load_map(tmp_path / "ab.map")
    assert gmap.stats()["features"] == built.stats()["features"] > 1000
    # A saved map plus a log: the log's submap joins the saved ones.
    subprocess.run([cli, "map", "build", "--out", str(tmp_path / "a.map"), str(a)], check=True, capture_output=True)
    more = lshloc.map_from_sources([str(tmp_path / "a.map"), str(b)])
    assert more.submap_names == gmap.submap_names and more.stats()["features"] == gmap.stats()["features"]
    with pytest.raises(lshloc.Error, match="fleet"):
        lshloc.map_from_sources(["redis://127.0.0.1:6379"])
    with pytest.raises(lshloc.Error, match="nothing follows the comma"):
        lshloc.map_from_sources([str(a) + ","])


def test_the_cli_is_found_without_lshloc_cli(tmp_path):
    """LSHLOC_CLI, else lshloc on PATH, else the repository's build; None (the tests that need it skip) without."""
    root, bin_dir = tmp_path / "repo", tmp_path / "bin"
    assert find_cli({"PATH": ""}, root) is None
    built = root / "build" / "bin" / "lshloc"
    built.parent.mkdir(parents=True)
    built.write_text("#!/bin/sh\n")
    built.chmod(0o755)
    assert find_cli({"PATH": ""}, root) == str(built)
    bin_dir.mkdir()
    shutil.copy(built, bin_dir / "lshloc")
    assert find_cli({"PATH": str(bin_dir)}, root) == str(bin_dir / "lshloc")
    assert find_cli({"PATH": str(bin_dir), "LSHLOC_CLI": "/opt/x/lshloc"}, root) == "/opt/x/lshloc"


def test_help_states_the_conventions():
    for phrase in ("(x, y, theta) tuples [m, m, rad]", "`robot_pose` is the robot's", "NaN", ">= max_range",
                   "release the GIL", "exclusively", "A Localizer serializes its own calls"):
        assert phrase in lshloc.__doc__, phrase
    assert "odometry" in lshloc.LaserScan.__init__.__doc__
    for array in (lshloc.LaserScan.ranges, lshloc.LaserScan.angles, lshloc.OccupancyGrid.cells):
        assert "read-only copy" in array.__doc__
    assert "Localizer" in lshloc.CarmenLog.laser_offset.__doc__
    assert "[rad]" in lshloc.GlobalMap.add_grid_submap.__doc__


def ros_scan_message(scan, ros1=False, range_min=0.02):
    """A stand-in for rclpy's (or, with ros1, rospy's) sensor_msgs/LaserScan of `scan`: +inf for no return."""
    from types import SimpleNamespace
    import array
    sec = math.floor(scan.timestamp)
    nsec = round((scan.timestamp - sec) * 1e9)
    stamp = SimpleNamespace(secs=sec, nsecs=nsec) if ros1 else SimpleNamespace(sec=sec, nanosec=nsec)
    ranges = [math.inf if r >= scan.max_range else float(r) for r in scan.ranges]
    n = len(ranges)
    return SimpleNamespace(header=SimpleNamespace(stamp=stamp, frame_id="laser"), angle_min=scan.angle_min,
                           angle_max=scan.angle_min + (n - 1) * scan.angle_increment,
                           angle_increment=scan.angle_increment, time_increment=0.0, scan_time=0.0,
                           range_min=range_min, range_max=scan.max_range,
                           ranges=tuple(ranges) if ros1 else array.array("f", ranges), intensities=[])


def test_a_ros_laser_scan_message_reads_as_the_log_scan_and_localizes_alike(world):
    """LaserScan.from_ros takes rclpy's and rospy's messages (stamps, +inf no-return) to the scan the log
    gives, so that a ROS robot's scans localize as the converted log's."""
    target = lshloc.read_carmen_log(world / "sim-3-001" / "sim-3-001.log.gz")
    b = lshloc.read_carmen_log(world / "sim-3-001" / "sim-3-001-corrected.log.gz")
    gmap = lshloc.GlobalMap()
    feed(gmap, [("b", b.scans[:600])])
    from_log, from_ros = lshloc.Localizer(gmap), lshloc.Localizer(gmap)
    for i, scan in enumerate(target.scans[700:760]):
        msg = ros_scan_message(scan, ros1=i % 2 == 1)
        ros = lshloc.LaserScan.from_ros(msg, odometry=scan.odometry)
        assert abs(ros.timestamp - scan.timestamp) < 1e-6 and ros.max_range == scan.max_range
        assert np.array_equal(ros.ranges, np.minimum(scan.ranges, scan.max_range))
        estimate = from_ros.add_scan(ros)
        assert estimate == from_log.add_scan(scan)
    assert estimate["has_estimate"] and estimate["submap"] == 0


def test_ros_beams_out_of_range_follow_the_converters_rules():
    """+inf or above range_max: no return (range_max); NaN, -inf or below range_min: invalid (NaN); the
    message's own array is left as it was."""
    from types import SimpleNamespace
    given = np.array([1.0, math.inf, 9.0, math.nan, -math.inf, 0.01, 7.5], dtype=np.float32)
    msg = SimpleNamespace(header=SimpleNamespace(stamp=SimpleNamespace(sec=12, nanosec=500_000_000)),
                          angle_min=-0.3, angle_increment=0.1, range_min=0.05, range_max=8.0, ranges=given)
    scan = lshloc.LaserScan.from_ros(msg)
    assert scan.timestamp == 12.5 and scan.max_range == 8.0 and scan.angle_min == -0.3
    want = [1.0, 8.0, 8.0, math.nan, math.nan, math.nan, 7.5]
    assert np.array_equal(scan.ranges, np.array(want, dtype=np.float32), equal_nan=True)
    assert np.isinf(given[1]) and given[2] == 9.0  # not changed in place
    del msg.range_min
    with pytest.raises(lshloc.Error, match="no field 'range_min'"):
        lshloc.LaserScan.from_ros(msg)
    msg.range_min = 0.05
    msg.header.stamp = SimpleNamespace(seconds=1)
    with pytest.raises(lshloc.Error, match="neither sec/nanosec"):
        lshloc.LaserScan.from_ros(msg)


def test_poses_from_ros_odometry_pose_and_transform_messages():
    """pose_from_ros reads (x, y, yaw) from each message shape a robot publishes; LaserScan.from_ros takes the
    odometry message itself."""
    from types import SimpleNamespace as N
    yaw = 2.5
    q = N(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))
    pose = N(position=N(x=1.5, y=-2.0, z=0.3), orientation=q)
    shapes = {
        "Odometry": N(header=None, child_frame_id="base_link", pose=N(pose=pose, covariance=[0.0] * 36)),
        "PoseWithCovarianceStamped": N(header=None, pose=N(pose=pose, covariance=[0.0] * 36)),
        "PoseStamped": N(header=None, pose=pose),
        "Pose": pose,
        "TransformStamped": N(header=None, child_frame_id="laser",
                              transform=N(translation=N(x=1.5, y=-2.0, z=0.3), rotation=q)),
    }
    for name, msg in shapes.items():
        x, y, th = lshloc.pose_from_ros(msg)
        assert (x, y) == (1.5, -2.0) and abs(th - yaw) < 1e-12, name
    with pytest.raises(lshloc.Error, match="expected a nav_msgs/Odometry"):
        lshloc.pose_from_ros(N(x=1.0))
    scan = N(header=N(stamp=N(sec=3, nanosec=0)), angle_min=-0.1, angle_increment=0.1, range_min=0.0,
             range_max=10.0, ranges=[1.0, 2.0, 3.0])
    assert lshloc.LaserScan.from_ros(scan, odometry=shapes["Odometry"]).odometry == lshloc.pose_from_ros(pose)
    assert lshloc.LaserScan.from_ros(scan, odometry=(1.0, 2.0, 0.5)).odometry == (1.0, 2.0, 0.5)
