"""scripts/tools/rosbag_to_carmen.py against known answers: a simulated robot's raw
log turned into ROS 2 bags (sqlite3 and MCAP, plain, zstd and lz4 chunks) by
this file's own CDR encoder and bag writers, converted back and compared scan
by scan and by localizing it; the same bags compressed by rosbag2's file and
message modes, and with the laser mount on /tf; ROS 1 bags (plain, bz2 and lz4
chunks, without an index, cut off) by this file's own ROS 1 encoder and bag
writer; CDR and ROS 1 golden bytes written out by hand; an upside-down laser;
and bad input."""
import bz2
import gzip
import itertools
import json
import math
import os
import pathlib
import sqlite3
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest

lshloc = pytest.importorskip("lshloc")

ROOT = pathlib.Path(__file__).resolve().parents[2]
CONVERTER = ROOT / "scripts" / "tools" / "rosbag_to_carmen.py"
LASER_SCAN, ODOMETRY, TF_MESSAGE = "sensor_msgs/msg/LaserScan", "nav_msgs/msg/Odometry", "tf2_msgs/msg/TFMessage"
# The mount put in /tf_static on top of the simulated log's own laser offset.
MOUNT_SHIFT = (0.0, 0.07, 0.05)
ODOM_SHIFTED_EVERY = 10  # every 10th scan's odometry comes as two messages around it, not one at its stamp
BAG_LATENCY_NS = 7_000_000  # the bag's receive time is the header stamp plus this


def cli():
    if os.environ.get("LSHLOC_CLI"):
        return os.environ["LSHLOC_CLI"]
    built = ROOT / "build" / "bin" / "lshloc"
    return str(built) if built.exists() else None


def convert(bag, out, *options, expect_ok=True, env=None, quiet=True):
    """env: variables added to the converter's environment."""
    run = subprocess.run([sys.executable, str(CONVERTER), str(bag), "--out", str(out), *(["--quiet"] * quiet),
                          *options],
                         capture_output=True, text=True, env={**os.environ, **env} if env else None)
    if expect_ok:
        assert run.returncode == 0, run.stderr
    return run


# ---------------------------------------------------------------- CDR encoder


class CdrWriter:
    """XCDR1: the encapsulation header, then each primitive aligned to its size from the end of the header."""

    def __init__(self, big_endian=False):
        self.order = ">" if big_endian else "<"
        self.header = b"\x00\x00\x00\x00" if big_endian else b"\x00\x01\x00\x00"
        self.body = bytearray()

    def put(self, code, *values):
        size = struct.calcsize(code)
        self.body += b"\x00" * (-len(self.body) % size)
        self.body += struct.pack(f"{self.order}{len(values)}{code}", *values)

    def string(self, text):
        encoded = text.encode() + b"\x00"
        self.put("I", len(encoded))
        self.body += encoded

    def stamp_header(self, stamp_ns, frame):
        self.put("i", stamp_ns // 1_000_000_000)
        self.put("I", stamp_ns % 1_000_000_000)
        self.string(frame)

    def data(self):
        return self.header + bytes(self.body)


class Ros1Writer:
    """ROS 1's serialization: little-endian, packed; strings and variable arrays after a u32 length, fixed arrays
    without. A Header is u32 seq, u32 sec, u32 nsec, frame_id; seq counts up from one writer to the next."""
    sequence = itertools.count(1)

    def __init__(self, seq=None):
        self.seq = next(Ros1Writer.sequence) if seq is None else seq
        self.body = bytearray()

    def put(self, code, *values):
        self.body += struct.pack(f"<{len(values)}{code}", *values)

    def string(self, text):
        encoded = text.encode()
        self.put("I", len(encoded))
        self.body += encoded

    def stamp_header(self, stamp_ns, frame):
        self.put("I", self.seq % 2**32, stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000)
        self.string(frame)

    def data(self):
        return bytes(self.body)


def laser_scan_cdr(stamp_ns, frame, angle_min, angle_increment, ranges, range_min=0.02, range_max=30.0,
                   big_endian=False, writer=None):
    """writer: a Ros1Writer for ROS 1's serialization; by default CDR."""
    w = writer or CdrWriter(big_endian)
    w.stamp_header(stamp_ns, frame)
    angle_max = angle_min + (len(ranges) - 1) * angle_increment
    w.put("f", angle_min, angle_max, angle_increment, 0.0, 0.25, range_min, range_max)  # scan_time 0.25 s
    w.put("I", len(ranges))
    w.put("f", *ranges)
    w.put("I", 0)
    return w.data()


def yaw_quaternion(yaw):
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def odometry_cdr(stamp_ns, x, y, yaw=0.0, rotation=None, frame="odom", child="base_link", big_endian=False,
                 writer=None):
    w = writer or CdrWriter(big_endian)
    w.stamp_header(stamp_ns, frame)
    w.string(child)
    w.put("d", x, y, 0.0, *(rotation or yaw_quaternion(yaw)))
    w.put("d", *([0.0] * 36))
    w.put("d", *([0.0] * 6))
    w.put("d", *([0.0] * 36))
    return w.data()


def tf_cdr(stamp_ns, transforms, writer=None):
    """transforms: (parent, child, (x, y, z), (qx, qy, qz, qw))."""
    w = writer or CdrWriter()
    w.put("I", len(transforms))
    for parent, child, translation, rotation in transforms:
        w.stamp_header(stamp_ns, parent)
        w.string(child)
        w.put("d", *translation)
        w.put("d", *rotation)
    return w.data()


# ---------------------------------------------------------------- bag writers


def write_sqlite(path, topics, messages):
    """topics: {name: type}; messages: (topic, bag time [ns], data), with rosbag2's tables."""
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, "
               "serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL)")
    db.execute("CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, "
               "timestamp INTEGER NOT NULL, data BLOB NOT NULL)")
    ids = {name: i for i, name in enumerate(topics, start=1)}
    db.executemany("INSERT INTO topics VALUES (?, ?, ?, 'cdr', '')", [(i, n, topics[n]) for n, i in ids.items()])
    db.executemany("INSERT INTO messages(topic_id, timestamp, data) VALUES (?, ?, ?)",
                   [(ids[topic], stamp, data) for topic, stamp, data in messages])
    db.commit()
    db.close()


MCAP_MAGIC = b"\x89MCAP0\r\n"


def mcap_string(text):
    return struct.pack("<I", len(text)) + text.encode()


def mcap_record(opcode, content):
    return struct.pack("<BQ", opcode, len(content)) + content


def write_mcap(path, topics, messages, compression=None, chunk_messages=400):
    """A minimal MCAP: header, schemas and channels, messages (in chunks when compressed), data end, footer."""
    definitions = b""
    channel_of = {}
    for i, (name, type_name) in enumerate(topics.items(), start=1):
        definitions += mcap_record(0x03, struct.pack("<H", i) + mcap_string(type_name) + mcap_string("ros2msg")
                                   + struct.pack("<I", 0))
        definitions += mcap_record(0x04, struct.pack("<HH", i, i) + mcap_string(name) + mcap_string("cdr")
                                   + struct.pack("<I", 0))
        channel_of[name] = i
    message_records = [mcap_record(0x05, struct.pack("<HIQQ", channel_of[topic], n, stamp, stamp) + data)
                       for n, (topic, stamp, data) in enumerate(messages)]
    out = MCAP_MAGIC + mcap_record(0x01, mcap_string("ros2") + mcap_string("test writer"))
    if compression is None:
        out += definitions + b"".join(message_records)
    else:
        for start in range(0, len(message_records), chunk_messages):
            records = (definitions if start == 0 else b"") + b"".join(message_records[start:start + chunk_messages])
            if compression == "zstd":
                import zstandard
                packed = zstandard.ZstdCompressor().compress(records)
            else:
                import lz4.frame
                packed = lz4.frame.compress(records)
            stamps = [m[1] for m in messages[start:start + chunk_messages]]
            out += mcap_record(0x06, struct.pack("<QQQI", min(stamps), max(stamps), len(records), zlib.crc32(records))
                               + mcap_string(compression) + struct.pack("<Q", len(packed)) + packed)
    out += mcap_record(0x0F, struct.pack("<I", 0))  # data end: a record the converter skips
    out += mcap_record(0x02, struct.pack("<QQI", 0, 0, 0)) + MCAP_MAGIC
    pathlib.Path(path).write_bytes(out)


# ---------------------------------------------------------------- golden bytes

# LaserScan{stamp 1 s 2 ns, frame "l", angle_min -0.5, angle_max 0.5, increment 1, time_increment 0,
# scan_time 0.25, range_min 0.125, range_max 8, ranges [1.5, 2], no intensities}, little-endian CDR.
GOLDEN_SCAN = bytes.fromhex(
    "00010000"                      # encapsulation: CDR little-endian
    "01000000" "02000000"           # sec, nanosec
    "02000000" "6c00" "0000"        # frame_id "l\0", then 2 bytes pad: floats align to 4 from the header's end
    "000000bf" "0000003f" "0000803f" "00000000" "0000803e" "0000003e" "00000041"
    "02000000" "0000c03f" "00000040"  # ranges [1.5, 2.0]
    "00000000")                     # no intensities
# Odometry{stamp 1 s 2 ns, frame "o", child "b", position (1, 2, 0), orientation (0, 0, 1, 0): yaw pi, rest 0}.
GOLDEN_ODOMETRY = bytes.fromhex(
    "00010000"
    "01000000" "02000000"
    "02000000" "6f00" "0000"        # frame_id "o\0", pad to 4
    "02000000" "6200" "0000"        # child_frame_id "b\0", pad to 24: doubles align to 8 from the header's end
    "000000000000f03f" "0000000000000040" "0000000000000000"            # position
    "0000000000000000" "0000000000000000" "000000000000f03f" "0000000000000000"  # orientation x y z w
) + bytes(8 * (36 + 6 + 36))


def test_the_encoder_writes_and_the_converter_reads_golden_cdr_bytes(tmp_path):
    assert laser_scan_cdr(1_000_000_002, "l", -0.5, 1.0, [1.5, 2.0], range_min=0.125, range_max=8.0) == GOLDEN_SCAN
    assert odometry_cdr(1_000_000_002, 1.0, 2.0, rotation=(0.0, 0.0, 1.0, 0.0), frame="o", child="b") \
        == GOLDEN_ODOMETRY
    for big_endian in (False, True):
        bag = tmp_path / f"golden-{big_endian}.db3"
        scan = laser_scan_cdr(1_000_000_002, "l", -0.5, 1.0, [1.5, 2.0], range_min=0.125, range_max=8.0,
                              big_endian=True) if big_endian else GOLDEN_SCAN
        odom = odometry_cdr(1_000_000_002, 1.0, 2.0, rotation=(0.0, 0.0, 1.0, 0.0), frame="o", child="b",
                            big_endian=True) if big_endian else GOLDEN_ODOMETRY
        write_sqlite(bag, {"/scan": LASER_SCAN, "/odom": ODOMETRY}, [("/scan", 5, scan), ("/odom", 5, odom)])
        out = tmp_path / f"golden-{big_endian}.log"
        assert_golden_log(convert(bag, out), out)


def assert_golden_log(run, out):
    """The log of the golden scan and odometry, at one time."""
    assert "no /tf_static transforms and no --laser-offset" in run.stderr
    fields = out.read_text().splitlines()[1].split()
    assert fields[:12] == ["ROBOTLASER1", "0", "-0.5", "1", "1", "8", "0.01", "0", "2", "1.5", "2", "0"]
    numbers = [float(v) for v in fields[12:18]]
    assert numbers[:2] == [1.0, 2.0] and numbers[3:5] == [1.0, 2.0]
    assert abs(math.cos(numbers[2]) + 1) < 1e-12 and abs(math.cos(numbers[5]) + 1) < 1e-12  # yaw pi
    assert fields[18:] == ["0"] * 5 + ["1.000000002", "rosbag", "1.000000002"]


# ---------------------------------------------------------------- the simulated robot as a bag


def compose(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], math.atan2(math.sin(a[2] + b[2]),
                                                                               math.cos(a[2] + b[2])))


def inverse(a):
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2])


def angle_diff(a, b):
    return abs(math.atan2(math.sin(a - b), math.cos(a - b)))


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    if cli() is None:
        pytest.skip("no lshloc CLI: set LSHLOC_CLI or build build/bin/lshloc")
    d = tmp_path_factory.mktemp("sim")
    subprocess.run([cli(), "simulate", "--out", str(d), "--buildings", "2", "--seed", "3", "--scans", "1200"],
                   check=True, capture_output=True)
    return d


class TargetBag:
    """The raw target log as bag messages, and what its conversion must give back. writer: makes each message's
    encoder, CdrWriter or Ros1Writer."""

    def __init__(self, log_path, writer=CdrWriter):
        self.writer = writer
        log = lshloc.read_carmen_log(str(log_path))
        self.original = log
        self.mount = tuple(o + s for o, s in zip(log.laser_offset, MOUNT_SHIFT))
        self.stamps = [round(scan.timestamp * 1e9) for scan in log.scans]
        # The laser keeps its true poses: the robot is where the new mount puts the laser there.
        self.robot = [compose(scan.pose, inverse(self.mount)) for scan in log.scans]
        self.expected_ranges = []
        self.messages = []
        self.topics = {"/scan": LASER_SCAN, "/odom": ODOMETRY, "/tf_static": TF_MESSAGE}
        x, y, theta = self.mount
        # The chain base_link -> laser walks the first edge backwards.
        self.mount_tf = [("base_footprint", "base_link", (0.0, 0.0, 0.1), (0.0, 0.0, 0.0, 1.0)),
                         ("base_footprint", "laser", (x, y, 0.25), yaw_quaternion(theta))]
        self.messages.append(("/tf_static", self.stamps[0] - 10**9, tf_cdr(self.stamps[0], self.mount_tf,
                                                                           writer=writer())))
        self.messages.append(("/tf_static", self.stamps[0] - 10**9, tf_cdr(self.stamps[0], [
            ("base_link", "imu", (0.0, 0.0, 0.2), (0.0, 0.0, 0.0, 1.0))], writer=writer())))
        for i, scan in enumerate(log.scans):
            ranges, expected = self.ros_ranges(i, scan)
            self.expected_ranges.append(expected)
            self.messages.append(("/scan", self.stamps[i] + BAG_LATENCY_NS, laser_scan_cdr(
                self.stamps[i], "laser", scan.angle_min, scan.angle_increment, ranges, range_max=scan.max_range,
                writer=writer())))
            self.messages.extend(self.odometry_messages(i))

    def ros_ranges(self, i, scan):
        """ROS conventions: no return as +inf or beyond range_max; the first scans also get invalid beams."""
        ranges = scan.ranges.astype(np.float32)
        expected = np.where(ranges >= scan.max_range, np.float32(scan.max_range), ranges)
        far = np.flatnonzero(ranges >= scan.max_range)
        ranges[far[0::2]] = np.inf
        ranges[far[1::2]] = scan.max_range + 5.0
        if i < 5:
            ranges[[0, 1, 2]] = [np.nan, -np.inf, 0.001]  # NaN, -inf, below range_min: all invalid
            expected[[0, 1, 2]] = np.nan
        return ranges.tolist(), expected

    def odometry_messages(self, i):
        stamp, (x, y, yaw) = self.stamps[i], self.robot[i]
        if i % ODOM_SHIFTED_EVERY != ODOM_SHIFTED_EVERY // 2 or i + 1 == len(self.stamps):
            return [("/odom", stamp + BAG_LATENCY_NS, odometry_cdr(stamp, x, y, yaw, writer=self.writer()))]
        # Two messages 3 ms before and 5 ms after, on a line through the pose at the scan's stamp.
        velocity = (0.4, -0.2, 0.3)
        out = []
        for dt_ns in (-3_000_000, 5_000_000):
            dt = dt_ns * 1e-9
            out.append(("/odom", stamp + dt_ns + BAG_LATENCY_NS, odometry_cdr(
                stamp + dt_ns, x + velocity[0] * dt, y + velocity[1] * dt, yaw + velocity[2] * dt,
                writer=self.writer())))
        return out


@pytest.fixture(scope="module")
def target(world):
    return TargetBag(world / "sim-3-001" / "sim-3-001.log.gz")


@pytest.fixture(scope="module")
def sqlite_log(target, tmp_path_factory):
    d = tmp_path_factory.mktemp("sqlite")
    bag = d / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    write_sqlite(bag / "bag_0.db3", target.topics, target.messages)
    out = d / "converted.log.gz"
    run = convert(bag, out)
    assert "wrote 1200 scans" in run.stderr
    assert "/tf_static base_link -> laser" in run.stderr
    return out


def test_a_sqlite_bag_converts_back_to_the_original_scans(target, sqlite_log):
    log = lshloc.read_carmen_log(str(sqlite_log))
    assert len(log) == len(target.original)
    for i, (got, want) in enumerate(zip(log.scans, target.original.scans)):
        assert np.array_equal(got.ranges, target.expected_ranges[i], equal_nan=True), i
        assert got.max_range == np.float32(want.max_range)
        assert abs(got.angle_min - want.angle_min) < 1e-6 and abs(got.angle_increment - want.angle_increment) < 1e-6
        assert abs(got.timestamp - want.timestamp) < 1e-6
        for g, w in ((got.odometry, target.robot[i]), (got.pose, want.pose)):
            assert math.hypot(g[0] - w[0], g[1] - w[1]) < 1e-6 and angle_diff(g[2], w[2]) < 1e-6, i
    assert all(abs(g - w) < 1e-6 for g, w in zip(log.laser_offset, target.mount))
    assert sqlite_log.read_bytes()[:2] == b"\x1f\x8b"  # .gz: gzip
    with gzip.open(sqlite_log, "rt") as f:
        assert f.readline().startswith("# converted by rosbag_to_carmen.py from ")


@pytest.mark.parametrize("compression", [None, "zstd", "lz4"])
def test_mcap_bags_give_the_same_log_as_sqlite(target, sqlite_log, tmp_path, compression):
    if compression:
        pytest.importorskip({"zstd": "zstandard", "lz4": "lz4.frame"}[compression])
    bag = tmp_path / "bag.mcap"
    write_mcap(bag, target.topics, target.messages, compression)
    out = tmp_path / "converted.log.gz"
    convert(bag, out)
    with gzip.open(out, "rt") as got, gzip.open(sqlite_log, "rt") as want:
        assert got.read().splitlines()[1:] == want.read().splitlines()[1:]


def test_the_laser_offset_option_overrides_tf_static(target, tmp_path):
    bag = tmp_path / "bag.db3"
    write_sqlite(bag, target.topics, target.messages)
    out = tmp_path / "converted.log"
    run = convert(bag, out, "--laser-offset=-0.2,0.1,-0.3")
    assert "from --laser-offset" in run.stderr
    log = lshloc.read_carmen_log(str(out))
    assert all(abs(g - w) < 1e-6 for g, w in zip(log.laser_offset, (-0.2, 0.1, -0.3)))
    want = compose(target.robot[7], (-0.2, 0.1, -0.3))
    got = log.scans[7].pose
    assert math.hypot(got[0] - want[0], got[1] - want[1]) < 1e-6 and angle_diff(got[2], want[2]) < 1e-6


def test_bag_stamps_are_the_receive_times(target, tmp_path):
    bag = tmp_path / "bag.db3"
    write_sqlite(bag, target.topics, target.messages)
    out = tmp_path / "converted.log"
    convert(bag, out, "--stamp", "bag")
    log = lshloc.read_carmen_log(str(out))
    assert len(log) == len(target.original)
    for got, want, robot in zip(log.scans, target.original.scans, target.robot):
        assert abs(got.timestamp - (want.timestamp + BAG_LATENCY_NS * 1e-9)) < 1e-6
        assert math.hypot(got.odometry[0] - robot[0], got.odometry[1] - robot[1]) < 1e-6


def localize(log, world):
    maps = [a for n in ("000", "001") for a in ("--map", str(world / f"sim-3-{n}" / f"sim-3-{n}-corrected.log.gz"))]
    run = subprocess.run([cli(), "localize", *maps, "--target", str(log), "--start", "300", "--length", "150",
                          "--json"], capture_output=True, text=True, check=True)
    return json.loads(run.stdout.strip().splitlines()[-1])


def test_the_converted_log_localizes_as_the_original(world, sqlite_log):
    got = localize(sqlite_log, world)
    want = localize(world / "sim-3-001" / "sim-3-001.log.gz", world)
    assert got["localized"] and want["localized"]
    assert got["final_submap"] == want["final_submap"]
    # final_pose is the laser's pose, the same in both logs
    assert math.hypot(got["final_pose"][0] - want["final_pose"][0], got["final_pose"][1] - want["final_pose"][1]) \
        < 0.05


# ---------------------------------------------------------------- rosbag2 compression

ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"


def log_body(path):
    """A converted log's bytes after its first line, the comment naming the bag."""
    with (gzip.open if str(path).endswith(".gz") else open)(path, "rb") as f:
        f.readline()
        return f.read()


def write_storage(path, storage, topics, messages):
    if storage == "db3":
        write_sqlite(path, topics, messages)
    else:
        write_mcap(path, topics, messages)


def write_metadata(bag_dir, files, mode="", compression=""):
    """metadata.yaml as rosbag2 (version 5) writes it: the keys the converter reads among the others."""
    listed = "".join(f"    - {name}\n" for name in files)
    described = "".join(f"    - path: {name}\n      starting_time:\n        nanoseconds_since_epoch: 0\n"
                        "      duration:\n        nanoseconds: 0\n      message_count: 0\n" for name in files)
    empty = '""'
    (bag_dir / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n"
        "  version: 5\n"
        "  storage_identifier: sqlite3\n"
        "  duration:\n    nanoseconds: 0\n"
        "  starting_time:\n    nanoseconds_since_epoch: 0\n"
        "  message_count: 0\n"
        "  topics_with_message_count:\n"
        "    - topic_metadata:\n"
        "        name: /scan\n"
        "        type: sensor_msgs/msg/LaserScan\n"
        "        serialization_format: cdr\n"
        '        offered_qos_profiles: "- history: 3\\n  depth: 0\\n  reliability: 1"\n'
        "      message_count: 0\n"
        f"  compression_format: {compression or empty}\n"
        f"  compression_mode: {mode or empty}\n"
        f"  relative_file_paths:\n{listed}"
        f"  files:\n{described}")


def zstd_pack(data, packing):
    """zstd frames as rosbag2 or the zstd tool may write them: one frame holding its size, one streamed without
    it, or two frames."""
    import zstandard
    compressor = zstandard.ZstdCompressor()
    if packing == "one frame":
        packed = compressor.compress(data)
        assert zstandard.frame_content_size(packed) == len(data)
    elif packing == "streamed":
        stream = compressor.compressobj()
        packed = stream.compress(data) + stream.flush()
        assert zstandard.frame_content_size(packed) == -1  # the frame header holds no content size
    else:
        half = len(data) // 2
        packed = compressor.compress(data[:half]) + compressor.compress(data[half:])
    return packed


@pytest.mark.parametrize("storage, packing, mode", [
    ("db3", "one frame", "FILE"), ("db3", "streamed", "file"), ("db3", "two frames", "FILE"),
    ("mcap", "one frame", "FILE"), ("mcap", "streamed", "file")])
def test_bags_compressed_whole_give_the_same_log(target, sqlite_log, tmp_path, storage, packing, mode):
    pytest.importorskip("zstandard")
    plain = tmp_path / f"plain.{storage}"
    write_storage(plain, storage, target.topics, target.messages)
    bag = tmp_path / "bag"
    bag.mkdir()
    name = f"bag_0.{storage}.zstd"
    (bag / name).write_bytes(zstd_pack(plain.read_bytes(), packing))
    write_metadata(bag, [name], mode, "zstd")
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    for given in (bag, bag / name):  # the directory, and the file alone: known by its magic bytes
        out = tmp_path / "out.log.gz"
        run = convert(given, out, env={"TMPDIR": str(scratch)}, quiet=False)
        assert "wrote 1200 scans" in run.stderr
        assert f"in {scratch}{os.sep}rosbag_to_carmen-" in run.stderr  # decompressed into a temporary file
        assert log_body(out) == log_body(sqlite_log)
        assert list(scratch.iterdir()) == []  # which is gone


def test_a_bag_of_several_compressed_files_reads_those_metadata_yaml_lists(target, sqlite_log, tmp_path):
    pytest.importorskip("zstandard")
    bag = tmp_path / "bag"
    bag.mkdir()
    half = len(target.messages) // 2
    write_sqlite(bag / "bag_0.db3", target.topics, target.messages[:half])
    (bag / "bag_0.db3.zstd").write_bytes(zstd_pack((bag / "bag_0.db3").read_bytes(), "streamed"))
    (bag / "bag_0.db3").unlink()
    write_sqlite(bag / "bag_1.db3", target.topics, target.messages[half:])  # listed as .zstd, decompressed by hand
    (bag / "bag_2.db3").write_text("not listed in metadata.yaml, so never read\n")
    # rosbag2 before version 4 listed paths with the bag directory's name in front
    write_metadata(bag, ["bag/bag_0.db3.zstd", "bag_1.db3.zstd"], "FILE", "zstd")
    out = tmp_path / "out.log.gz"
    convert(bag, out)
    assert log_body(out) == log_body(sqlite_log)


@pytest.mark.parametrize("storage", ["db3", "mcap"])
def test_bags_of_compressed_messages_give_the_same_log(target, sqlite_log, tmp_path, storage):
    pytest.importorskip("zstandard")
    # every other message streamed: its frame holds no content size
    messages = [(topic, stamp, zstd_pack(data, "streamed" if n % 2 else "one frame"))
                for n, (topic, stamp, data) in enumerate(target.messages)]
    bag = tmp_path / "bag"
    bag.mkdir()
    write_storage(bag / f"bag_0.{storage}", storage, target.topics, messages)
    write_metadata(bag, [f"bag_0.{storage}"], "MESSAGE", "zstd")
    for given in (bag, bag / f"bag_0.{storage}"):  # the file alone: each message known by its magic bytes
        out = tmp_path / "out.log.gz"
        convert(given, out)
        assert log_body(out) == log_body(sqlite_log)


# ---------------------------------------------------------------- the laser mount on /tf


def write_tf_bag(target, path, static_mount, tf_mount):
    """The target bag with the mount transforms `static_mount` on /tf_static (the imu's stays), odom -> base_link
    on /tf at each scan (/tf message i + 1 at scan i), and at every 100th scan, the k-th, tf_mount(k) with it."""
    messages = target.messages[1:]
    if static_mount:
        messages.append(("/tf_static", target.stamps[0] - 10**9, tf_cdr(target.stamps[0], static_mount)))
    for i, stamp in enumerate(target.stamps):
        x, y, yaw = target.robot[i]
        transforms = [("odom", "base_link", (x, y, 0.0), yaw_quaternion(yaw))]
        if i % 100 == 0:
            transforms += tf_mount(i // 100)
        messages.append(("/tf", stamp + BAG_LATENCY_NS, tf_cdr(stamp, transforms)))
    write_sqlite(path, {**target.topics, "/tf": TF_MESSAGE}, messages)


def moved(transform, dx=0.0, dyaw=0.0):
    parent, child, (x, y, z), (qx, qy, qz, qw) = transform
    yaw = 2 * math.atan2(qz, qw)
    return parent, child, (x + dx, y, z), yaw_quaternion(yaw + dyaw)


@pytest.mark.parametrize("split", [False, True])
def test_a_laser_mount_on_tf_gives_the_same_log_as_on_tf_static(target, sqlite_log, tmp_path, split):
    """The chain base_link -> base_footprint -> laser all on /tf, or its first link on /tf_static (split)."""
    footprint_base, footprint_laser = target.mount_tf

    def tf_mount(k):
        # 0.4 mm and 0.05 degrees off the first: within a fixed mount's tolerance, and the first value is used
        laser = moved(footprint_laser, 0.0004, math.radians(0.05)) if k == 5 else footprint_laser
        return [laser] if split else [footprint_base, laser]

    bag = tmp_path / "bag.db3"
    write_tf_bag(target, bag, [footprint_base] if split else [], tf_mount)
    out = tmp_path / "out.log.gz"
    run = convert(bag, out)
    source = "/tf_static and /tf" if split else "/tf"
    assert f"from {source} base_link -> laser" in run.stderr
    assert log_body(out) == log_body(sqlite_log)
    with gzip.open(out, "rt") as f:
        assert f.readline().rstrip().endswith("(topics /scan, /odom" + (", /tf_static, /tf)" if split else ", /tf)"))


def test_tf_static_wins_over_tf(target, sqlite_log, tmp_path):
    bag = tmp_path / "bag.db3"
    # /tf's base_footprint -> laser moves 5 cm and 0.1 rad at each message: not read, as /tf_static has the chain
    write_tf_bag(target, bag, target.mount_tf, lambda k: [moved(target.mount_tf[1], 0.05 * k, 0.1 * k)])
    out = tmp_path / "out.log.gz"
    run = convert(bag, out)
    assert "from /tf_static base_link -> laser" in run.stderr
    assert log_body(out) == log_body(sqlite_log)


def test_a_laser_that_moves_on_tf_is_refused(target, tmp_path):
    footprint_base, footprint_laser = target.mount_tf
    out = tmp_path / "out.log"
    for name, change, numbers in (("shift", (0.05, 0.0), "50.0 mm and 0.00 degrees"),
                                  ("turn", (0.0, math.radians(0.2)), "0.0 mm and 0.20 degrees")):
        bag = tmp_path / f"{name}.db3"
        write_tf_bag(target, bag, [], lambda k: [footprint_base, moved(footprint_laser, *change) if k == 3
                                                 else footprint_laser])
        assert_refused(convert(bag, out, expect_ok=False), str(bag), "/tf message 301: base_footprint -> laser",
                       f"is {numbers} from its value in message 1", "the laser moves relative to the base",
                       "--laser-offset")
    run = convert(bag, out, "--laser-offset=0.1,0.2,0.3")
    assert "from --laser-offset" in run.stderr


# ---------------------------------------------------------------- ROS 1 bags

ROS1_MAGIC = b"#ROSBAG V2.0\n"
ROS1_NAMES = {LASER_SCAN: "sensor_msgs/LaserScan", ODOMETRY: "nav_msgs/Odometry", TF_MESSAGE: "tf2_msgs/TFMessage"}
ROS1_HEADER_RECORD_SIZE = 4096  # rosbag pads the bag header record to this, to rewrite it in place when closing


def u32(value):
    return struct.pack("<I", value)


def ros1_time(ns):
    return struct.pack("<II", ns // 1_000_000_000, ns % 1_000_000_000)


def ros1_header(fields):
    """A record header or connection header: each field u32 length, then name=value."""
    return b"".join(u32(len(name) + 1 + len(value)) + name.encode() + b"=" + value for name, value in fields)


def ros1_record(fields, data=b""):
    header = ros1_header(fields)
    return u32(len(header)) + header + u32(len(data)) + data


# The md5sums rosbag records for the standard definitions (`rosbag info` lists them).
ROS1_MD5 = {"sensor_msgs/LaserScan": b"90c7ef2dc6895d81024acba2ac42f369",
            "nav_msgs/Odometry": b"cd5e73d190d741a2f92e81eda573aca7",
            "tf2_msgs/TFMessage": b"94810edda583a504dfda3829e70d7eec",
            "tf/tfMessage": b"94810edda583a504dfda3829e70d7eec"}


def ros1_connection(conn, topic, type_name, md5=None):
    return ros1_record([("op", b"\x07"), ("conn", u32(conn)), ("topic", topic.encode())], ros1_header([
        ("topic", topic.encode()), ("type", type_name.encode()), ("md5sum", md5 or ROS1_MD5.get(type_name, b"0" * 32)),
        ("message_definition", b"# left out: the converter knows the layouts it reads\n")]))


def ros1_message(conn, stamp_ns, data):
    return ros1_record([("op", b"\x02"), ("conn", u32(conn)), ("time", ros1_time(stamp_ns))], data)


def ros1_chunk(records, compression="none", size=None):
    """A chunk record; compressions other than bz2 and lz4 are stored plain under their name."""
    if compression == "bz2":
        packed = bz2.compress(records)
    elif compression == "lz4":
        import lz4.frame
        packed = lz4.frame.compress(records)
    else:
        packed = records
    return ros1_record([("op", b"\x05"), ("compression", compression.encode()),
                        ("size", u32(len(records) if size is None else size))], packed)


def ros1_bag_header(index_pos=0, conn_count=0, chunk_count=0):
    fields = [("op", b"\x03"), ("index_pos", struct.pack("<Q", index_pos)), ("conn_count", u32(conn_count)),
              ("chunk_count", u32(chunk_count))]
    return ros1_record(fields, b" " * (ROS1_HEADER_RECORD_SIZE - 8 - len(ros1_header(fields))))


def write_ros1(path, topics, messages, compression="none", chunk_messages=400, index=True):
    """A ROS 1 bag (format 2.0) as rosbag writes it: the bag header record, chunks of connection and message data
    records each followed by its index data records, then the index section (connection and chunk info records),
    which index=False leaves out as in a recording cut off. topics: {name: ROS 1 type}; messages: (topic, bag time
    [ns], data). Returns each chunk's (offset, end offset, message count)."""
    conn_of = {name: i for i, name in enumerate(topics)}
    body, chunks, chunk_infos, seen = b"", [], b"", set()
    for start in range(0, len(messages), chunk_messages):
        group = messages[start:start + chunk_messages]
        records, entries = b"", {}
        for topic, stamp, data in group:
            if topic not in seen:
                seen.add(topic)
                records += ros1_connection(conn_of[topic], topic, topics[topic])
            entries.setdefault(conn_of[topic], []).append(ros1_time(stamp) + u32(len(records)))
            records += ros1_message(conn_of[topic], stamp, data)
        chunk_at = len(ROS1_MAGIC) + ROS1_HEADER_RECORD_SIZE + len(body)
        body += ros1_chunk(records, compression)
        chunks.append((chunk_at, len(ROS1_MAGIC) + ROS1_HEADER_RECORD_SIZE + len(body), len(group)))
        for conn, listed in entries.items():
            body += ros1_record([("op", b"\x04"), ("ver", u32(1)), ("conn", u32(conn)), ("count", u32(len(listed)))],
                                b"".join(listed))
        stamps = [stamp for _, stamp, _ in group]
        chunk_infos += ros1_record([("op", b"\x06"), ("ver", u32(1)), ("chunk_pos", struct.pack("<Q", chunk_at)),
                                    ("start_time", ros1_time(min(stamps))), ("end_time", ros1_time(max(stamps))),
                                    ("count", u32(len(entries)))],
                                   b"".join(u32(conn) + u32(len(listed)) for conn, listed in entries.items()))
    if index:
        header = ros1_bag_header(len(ROS1_MAGIC) + ROS1_HEADER_RECORD_SIZE + len(body), len(seen), len(chunks))
        body += b"".join(ros1_connection(conn_of[name], name, topics[name]) for name in topics if name in seen)
        body += chunk_infos
    else:
        header = ros1_bag_header()  # as rosbag leaves it until the bag is closed
    assert len(header) == ROS1_HEADER_RECORD_SIZE
    pathlib.Path(path).write_bytes(ROS1_MAGIC + header + body)
    return chunks


def ros1_topics(topics):
    return {name: ROS1_NAMES[type_name] for name, type_name in topics.items()}


@pytest.fixture(scope="module")
def ros1_target(world):
    return TargetBag(world / "sim-3-001" / "sim-3-001.log.gz", Ros1Writer)


@pytest.mark.parametrize("compression", ["none", "bz2", "lz4"])
def test_ros1_bags_give_the_same_log_as_sqlite(ros1_target, sqlite_log, tmp_path, compression):
    if compression == "lz4":
        pytest.importorskip("lz4.frame")
    bag = tmp_path / "run.bag"
    write_ros1(bag, ros1_topics(ros1_target.topics), ros1_target.messages, compression)
    out = tmp_path / "converted.log.gz"
    run = convert(bag, out)
    assert "from /tf_static base_link -> laser" in run.stderr and "warning" not in run.stderr
    assert log_body(out) == log_body(sqlite_log)


def test_a_ros1_bag_without_its_index_or_cut_off_reads_the_records_there(target, ros1_target, sqlite_log,
                                                                           tmp_path):
    recording = tmp_path / "recording"  # no .bag suffix: known by its first line
    chunks = write_ros1(recording, ros1_topics(ros1_target.topics), ros1_target.messages, "bz2", index=False)
    out = tmp_path / "out.log.gz"
    run = convert(recording, out)
    assert "warning" not in run.stderr
    assert log_body(out) == log_body(sqlite_log)

    # cut in the middle of the last chunk (then the last record): its messages are lost, the chunks before it read
    last_at, last_end, last_count = chunks[-1]
    cut = tmp_path / "cut.bag"
    cut.write_bytes(recording.read_bytes()[:(last_at + last_end) // 2])
    run = convert(cut, out)
    assert f"warning: {cut}: the file ends inside the record at byte {last_at}" in run.stderr
    assert "recording was cut off" in run.stderr
    kept = len(ros1_target.messages) - last_count
    assert 0 < kept < len(ros1_target.messages)
    before = tmp_path / "before.db3"
    write_sqlite(before, target.topics, target.messages[:kept])
    want = tmp_path / "want.log.gz"
    convert(before, want)
    assert log_body(out) == log_body(want)


def test_a_ros1_laser_mount_on_tf_in_tf_tfmessages_gives_the_same_log(ros1_target, sqlite_log, tmp_path):
    """tf/tfMessage, ROS 1's older transform message, on /tf: the chain base_link -> base_footprint -> laser at
    every 100th scan (once 0.4 mm and 0.05 degrees off, within a fixed mount's tolerance), odom -> base_link at
    each scan."""
    footprint_base, footprint_laser = ros1_target.mount_tf
    messages = ros1_target.messages[1:]  # /tf_static keeps only the imu
    for i, stamp in enumerate(ros1_target.stamps):
        x, y, yaw = ros1_target.robot[i]
        transforms = [("odom", "base_link", (x, y, 0.0), yaw_quaternion(yaw))]
        if i % 100 == 0:
            laser = moved(footprint_laser, 0.0004, math.radians(0.05)) if i == 500 else footprint_laser
            transforms += [footprint_base, laser]
        messages.append(("/tf", stamp + BAG_LATENCY_NS, tf_cdr(stamp, transforms, writer=Ros1Writer())))
    messages.sort(key=lambda message: message[1])
    bag = tmp_path / "tf.bag"
    write_ros1(bag, {**ros1_topics(ros1_target.topics), "/tf": "tf/tfMessage"}, messages)
    out = tmp_path / "out.log.gz"
    run = convert(bag, out)
    assert "from /tf base_link -> laser" in run.stderr
    assert log_body(out) == log_body(sqlite_log)
    with gzip.open(out, "rt") as f:
        assert f.readline().rstrip().endswith("(topics /scan, /odom, /tf)")


# LaserScan{seq 7, stamp 1 s 2 ns, frame "l", angle_min -0.5, angle_max 0.5, increment 1, time_increment 0,
# scan_time 0.25, range_min 0.125, range_max 8, ranges [1.5, 2], no intensities}, as GOLDEN_SCAN in ROS 1.
GOLDEN_ROS1_SCAN = bytes.fromhex(
    "07000000"                      # seq
    "01000000" "02000000"           # sec, nsec
    "01000000" "6c"                 # frame_id "l": no terminating NUL, no padding after it
    "000000bf" "0000003f" "0000803f" "00000000" "0000803e" "0000003e" "00000041"
    "02000000" "0000c03f" "00000040"  # ranges [1.5, 2.0]
    "00000000")                     # no intensities
# Odometry{seq 8, stamp 1 s 2 ns, frame "o", child "b", position (1, 2, 0), orientation (0, 0, 1, 0): yaw pi, rest 0}.
GOLDEN_ROS1_ODOMETRY = bytes.fromhex(
    "08000000"
    "01000000" "02000000"
    "01000000" "6f"                 # frame_id "o"
    "01000000" "62"                 # child_frame_id "b": the doubles follow unaligned
    "000000000000f03f" "0000000000000040" "0000000000000000"            # position
    "0000000000000000" "0000000000000000" "000000000000f03f" "0000000000000000"  # orientation x y z w
) + bytes(8 * (36 + 6 + 36))


def test_the_ros1_encoder_writes_and_the_converter_reads_golden_bytes(tmp_path):
    assert laser_scan_cdr(1_000_000_002, "l", -0.5, 1.0, [1.5, 2.0], range_min=0.125, range_max=8.0,
                          writer=Ros1Writer(7)) == GOLDEN_ROS1_SCAN
    assert odometry_cdr(1_000_000_002, 1.0, 2.0, rotation=(0.0, 0.0, 1.0, 0.0), frame="o", child="b",
                        writer=Ros1Writer(8)) == GOLDEN_ROS1_ODOMETRY
    bag = tmp_path / "golden.bag"
    write_ros1(bag, {"/scan": "sensor_msgs/LaserScan", "/odom": "nav_msgs/Odometry"},
               [("/scan", 5, GOLDEN_ROS1_SCAN), ("/odom", 5, GOLDEN_ROS1_ODOMETRY)])
    out = tmp_path / "golden.log"
    assert_golden_log(convert(bag, out), out)


def test_bad_ros1_bags_are_refused_naming_the_file_and_what_was_expected(tmp_path):
    out = tmp_path / "out.log"
    topics = {"/scan": "sensor_msgs/LaserScan"}
    scans = [("/scan", n, laser_scan_cdr(n, "laser", -0.1, 0.1, [1.0, 2.0], writer=Ros1Writer())) for n in (1, 2)]

    def refused(name, content, *parts):
        path = tmp_path / name
        path.write_bytes(content)
        assert_refused(convert(path, out, expect_ok=False), str(path), *parts)

    good = tmp_path / "good.bag"
    write_ros1(good, topics, scans)
    assert convert(good, out).returncode == 0
    refused("old.bag", b"#ROSBAG V1.2\n" + good.read_bytes()[len(ROS1_MAGIC):], "'#ROSBAG V1.2'",
            "a ROS 1 bag of format 1.2", "expected format 2.0")
    records = ros1_connection(0, "/scan", "sensor_msgs/LaserScan") + b"".join(
        ros1_message(0, stamp, data) for _, stamp, data in scans)
    start = ROS1_MAGIC + ros1_bag_header()
    chunk_at = len(start)
    refused("zstd.bag", start + ros1_chunk(records, "zstd"), f"chunk at byte {chunk_at} uses compression 'zstd'",
            "expected none, bz2 or lz4")
    refused("size.bag", start + ros1_chunk(records, "bz2", size=len(records) + 1),
            f"chunk at byte {chunk_at}: {len(records)} bytes uncompressed; expected {len(records) + 1}")
    stray = ros1_connection(0, "/scan", "sensor_msgs/LaserScan") + ros1_message(9, 1, scans[0][2])
    message_at = len(ros1_connection(0, "/scan", "sensor_msgs/LaserScan"))
    refused("stray.bag", start + ros1_chunk(stray), f"chunk at byte {chunk_at}, record at byte {message_at}",
            "a message on connection 9, which no connection record defined before it")
    # Another definition under the standard name: its bytes would decode to wrong numbers.
    custom = ros1_connection(0, "/scan", "sensor_msgs/LaserScan", md5=b"f" * 32)
    refused("custom.bag", start + ros1_chunk(custom + ros1_message(0, 1, scans[0][2])),
            f"topic /scan is sensor_msgs/LaserScan with md5sum {'f' * 32}", "expected 90c7ef2dc6895d81024acba2ac42f369")
    write_ros1(tmp_path / "short.bag", topics, [scans[0], ("/scan", 2, scans[1][2][:30])])
    refused("short.bag", (tmp_path / "short.bag").read_bytes(), "message 2 on topic /scan ends early",
            "expected a complete ROS 1-serialized sensor_msgs/LaserScan")


# ---------------------------------------------------------------- an upside-down laser


def test_an_upside_down_laser_sees_the_same_wall_as_an_upright_one(tmp_path):
    """A wall at x = 2 m in the base frame, seen by a laser yawed 0.2 rad, upright and flipped about its x-axis."""
    x, y, yaw = 0.3, 0.1, 0.2
    c, s = math.cos(yaw), math.sin(yaw)
    # Rotation matrix rows, quaternion (x, y, z, w), and the laser's first beam angle: the flipped laser sweeps
    # clockwise seen from above, so it covers the upright's beams, -0.3 to 0.5 rad from the mount's yaw, from -0.5.
    mounts = {
        "upright": ([[c, -s, 0], [s, c, 0], [0, 0, 1]], yaw_quaternion(yaw), -0.3),
        "flipped": ([[c, s, 0], [s, -c, 0], [0, 0, -1]], (math.cos(yaw / 2), math.sin(yaw / 2), 0.0, 0.0), -0.5),
    }
    n, increment = 41, np.float32(0.02)
    points, raw = {}, {}
    for name, (rotation, quaternion, first_angle) in mounts.items():
        angle_min = np.float32(first_angle)
        angles = angle_min + np.arange(n) * increment.astype(np.float64)
        # Ray-cast each beam in 3D: direction R (cos a, sin a, 0) from the laser's origin.
        dx = rotation[0][0] * np.cos(angles) + rotation[0][1] * np.sin(angles)
        raw[name] = ((2.0 - x) / dx).astype(np.float32)
        tf = [("base_link", "laser", (x, y, 0.25), quaternion)]
        messages = [("/tf_static", 0, tf_cdr(0, tf))]
        for k in range(3):
            stamp = 10**9 + k * 10**8
            messages.append(("/scan", stamp, laser_scan_cdr(stamp, "laser", angle_min, increment, raw[name].tolist())))
            messages.append(("/odom", stamp, odometry_cdr(stamp, 0.0, 0.0, 0.0)))
        bag = tmp_path / f"{name}.db3"
        write_sqlite(bag, {"/scan": LASER_SCAN, "/odom": ODOMETRY, "/tf_static": TF_MESSAGE}, messages)
        out = tmp_path / f"{name}.log"
        run = convert(bag, out)
        assert ("upside down" in run.stderr) == (name == "flipped")
        log = lshloc.read_carmen_log(str(out))
        assert all(abs(g - w) < 1e-6 for g, w in zip(log.laser_offset, (x, y, yaw)))
        scan = log.scans[0]
        expected = raw[name][::-1] if name == "flipped" else raw[name]  # the flipped scan mirrored
        assert np.array_equal(scan.ranges, expected)
        ox, oy, ot = log.laser_offset
        a = ot + scan.angles
        points[name] = np.stack([ox + scan.ranges * np.cos(a), oy + scan.ranges * np.sin(a)], axis=1)
        assert np.allclose(points[name][:, 0], 2.0, atol=1e-4), name
    assert np.allclose(points["upright"], points["flipped"], atol=1e-4)


# ---------------------------------------------------------------- odometry coverage


def tiny_bag(path, scan_stamps_s, odom_stamps_s, scan_topics=("/scan",)):
    topics = {t: LASER_SCAN for t in scan_topics}
    messages = []
    for topic in scan_topics:
        for t in scan_stamps_s:
            stamp = round(t * 1e9)
            messages.append((topic, stamp, laser_scan_cdr(stamp, "laser", -0.1, 0.1, [1.0, 2.0, 3.0])))
    if odom_stamps_s:
        topics["/odom"] = ODOMETRY
        for t in odom_stamps_s:
            messages.append(("/odom", round(t * 1e9), odometry_cdr(round(t * 1e9), t, 0.0, 2.6 + 0.5 * t)))
    write_sqlite(path, topics, messages)


def test_scans_outside_the_odometry_are_dropped_and_headings_interpolate_the_short_way(tmp_path):
    bag, out = tmp_path / "bag.db3", tmp_path / "out.log"
    tiny_bag(bag, [0.0, 0.6, 1.5, 2.4, 3.0], [1.0, 2.0])
    run = convert(bag, out)
    assert "dropped 2 scans" in run.stderr
    log = lshloc.read_carmen_log(str(out))
    assert [s.timestamp for s in log.scans] == [0.6, 1.5, 2.4]
    # headings 3.1 and 3.6 rad, the second written wrapped as -2.68: the middle is 3.35 rad, not 0.21
    x, _, heading = log.scans[1].odometry
    assert abs(x - 1.5) < 1e-6 and angle_diff(heading, 3.35) < 1e-6
    assert log.scans[0].odometry[0] == 1.0 and log.scans[2].odometry[0] == 2.0  # held at the ends, not extrapolated


def test_no_odometry_writes_zero_odometry_with_a_warning(tmp_path):
    bag, out = tmp_path / "bag.db3", tmp_path / "out.log"
    tiny_bag(bag, [0.0, 0.5], [])
    run = convert(bag, out)
    assert "--no-odometry" in run.stderr
    assert [s.odometry for s in lshloc.read_carmen_log(str(out)).scans] == [(0.0, 0.0, 0.0)] * 2


# ---------------------------------------------------------------- bad input


def assert_refused(run, *parts):
    assert run.returncode == 1, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("rosbag_to_carmen: error: "), run.stderr
    for part in parts:
        assert part in lines[0], lines[0]


def test_bad_input_is_refused_naming_the_file_and_what_was_expected(tmp_path):
    out = tmp_path / "out.log"
    good = tmp_path / "good.mcap"
    tiny_bag(tmp_path / "tiny.db3", [1.0, 1.1], [1.0, 1.1])
    db = sqlite3.connect(tmp_path / "tiny.db3")
    topics = {name: type_name for name, type_name in db.execute("SELECT name, type FROM topics")}
    messages = [(n, t, bytes(d)) for n, t, d in db.execute(
        "SELECT topics.name, timestamp, data FROM messages JOIN topics ON topics.id = topic_id")]
    db.close()
    write_mcap(good, topics, messages)
    truncated = tmp_path / "truncated.mcap"
    truncated.write_bytes(good.read_bytes()[:-60])
    assert_refused(convert(truncated, out, expect_ok=False), str(truncated), "byte ", "expected a whole record")

    cut = tmp_path / "cut.db3"
    write_sqlite(cut, {"/scan": LASER_SCAN}, [("/scan", 1, laser_scan_cdr(1, "laser", -0.1, 0.1, [1.0, 2.0])),
                                               ("/scan", 2, laser_scan_cdr(2, "laser", -0.1, 0.1, [1.0, 2.0])[:50])])
    assert_refused(convert(cut, out, expect_ok=False), str(cut), "message 2 on topic /scan ends early",
                   "expected a complete CDR-encoded sensor_msgs/msg/LaserScan")

    two = tmp_path / "two.db3"
    tiny_bag(two, [1.0], [1.0], scan_topics=("/scan_front", "/scan_rear"))
    assert_refused(convert(two, out, expect_ok=False), str(two), "2 sensor_msgs/msg/LaserScan topics",
                   "/scan_front, /scan_rear", "--scan-topic")
    assert convert(two, out, "--scan-topic", "/scan_rear").returncode == 0

    empty = tmp_path / "empty_dir"
    empty.mkdir()
    (empty / "notes.txt").write_text("not a bag\n")
    assert_refused(convert(empty, out, expect_ok=False), str(empty), "no .db3 or .mcap file",
                   "expected a ROS 2 bag directory")
    assert_refused(convert(tmp_path / "missing", out, expect_ok=False), "missing", "no such file or directory")
    text = tmp_path / "text.db3"
    text.write_text("hello\n")
    assert_refused(convert(text, out, expect_ok=False), str(text), "neither a sqlite3 database nor an MCAP file")
    no_scans = tmp_path / "no_scans.db3"
    write_sqlite(no_scans, {"/odom": ODOMETRY}, [("/odom", 1, odometry_cdr(1, 0.0, 0.0, 0.0))])
    assert_refused(convert(no_scans, out, expect_ok=False), str(no_scans), "no sensor_msgs/msg/LaserScan topic",
                   "/odom (nav_msgs/msg/Odometry)")


def test_bad_compressed_input_is_refused_and_leaves_no_temporary_file(tmp_path):
    zstandard = pytest.importorskip("zstandard")
    out = tmp_path / "out.log"
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    tiny_bag(tmp_path / "tiny.db3", [1.0, 1.1], [1.0, 1.1])
    data = (tmp_path / "tiny.db3").read_bytes()
    pack = zstandard.ZstdCompressor().compress

    def refused(name, content, *parts, env=None):
        path = tmp_path / name
        path.write_bytes(content)
        assert_refused(convert(path, out, expect_ok=False, env={"TMPDIR": str(scratch), **(env or {})}),
                       str(path), *parts)
        assert list(scratch.iterdir()) == []

    refused("plain.db3.zstd", data, "begins 53 51 4c 69, not a zstd frame", "expected a zstd-compressed ROS 2 "
            "storage file (zstd frames begin 28 b5 2f fd)")
    refused("cut.db3.zstd", pack(data)[:-40], "ends inside a zstd frame", "a truncated file")
    refused("garbled.db3.zstd", ZSTD_MAGIC + bytes(range(64)), "zstd says", "expected a valid zstd frame")
    refused("text.db3.zstd", pack(b"hello\n"), "decompressed, neither a sqlite3 database nor an MCAP file")
    refused("half.db3.zstd", pack(data[:len(data) // 2]), "not a readable rosbag2 database")
    shadow = tmp_path / "shadow"
    shadow.mkdir()
    (shadow / "zstandard.py").write_text("raise ImportError('hidden by the test')\n")
    refused("hidden.db3.zstd", pack(data), "is zstd-compressed and the Python module zstandard is missing",
            "apt install python3-zstandard", env={"PYTHONPATH": str(shadow)})

    # compression_mode message: each message must be a whole zstd frame
    bag = tmp_path / "bag"
    bag.mkdir()
    tiny_bag(bag / "bag_0.db3", [1.0, 1.1], [1.0, 1.1])
    write_metadata(bag, ["bag_0.db3"], "MESSAGE", "zstd")
    assert_refused(convert(bag, out, expect_ok=False), str(bag / "bag_0.db3"),
                   "message 1 on topic /scan begins 00 01 00 00, not a zstd frame", "compression_mode message")
    scan = laser_scan_cdr(1, "laser", -0.1, 0.1, [1.0, 2.0])
    damaged = tmp_path / "damaged.db3"
    write_sqlite(damaged, {"/scan": LASER_SCAN}, [("/scan", 1, pack(scan)), ("/scan", 2, pack(scan)[:-3])])
    assert_refused(convert(damaged, out, expect_ok=False), str(damaged),
                   "message 2 on topic /scan ends inside its zstd frame")
    write_metadata(bag, ["bag_0.db3"], "FILE", "lz4")
    assert_refused(convert(bag, out, expect_ok=False), str(bag / "metadata.yaml"), "compression_format 'lz4'",
                   "expected zstd")
    write_metadata(bag, ["bag_0.db3", "bag_1.db3.zstd"], "FILE", "zstd")
    assert_refused(convert(bag, out, expect_ok=False), str(bag / "metadata.yaml"),
                   "relative_file_paths lists bag_1.db3.zstd", "expected the bag's storage files beside metadata.yaml")


def small_bag_messages(writer_of):
    """A few scans and odometry messages, serialized by writer_of() (a CdrWriter or a Ros1Writer)."""
    messages = []
    for k in range(12):
        stamp = 1_000_000_000 + k * 100_000_000
        messages.append(("/scan", stamp, laser_scan_cdr(stamp, "laser", -0.1, 0.1, [1.0, 2.0, 3.0],
                                                         writer=writer_of())))
        messages.append(("/odom", stamp, odometry_cdr(stamp, 0.1 * k, 0.0, writer=writer_of())))
    return messages


@pytest.mark.parametrize("storage", ["db3", "mcap", "ros1-none", "ros1-bz2"])
def test_damaged_bags_are_refused_with_a_message_never_a_traceback(tmp_path, storage):
    """Seeded damage to a small bag (bytes flipped, runs zeroed, the file cut short): each run converts or exits 1
    with a one-line error naming the bag; no exception escapes the converter (run in-process: 150 runs a second)."""
    import contextlib
    import importlib.util
    import io
    import random
    spec = importlib.util.spec_from_file_location("rosbag_to_carmen_under_test", CONVERTER)
    converter = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(converter)
    good = tmp_path / "good.bag"
    if storage.startswith("ros1"):
        write_ros1(good, {"/scan": "sensor_msgs/LaserScan", "/odom": "nav_msgs/Odometry"},
                   small_bag_messages(Ros1Writer), compression=storage.split("-")[1], chunk_messages=8)
    else:
        write_storage(good, storage, {"/scan": LASER_SCAN, "/odom": ODOMETRY}, small_bag_messages(CdrWriter))
    original = good.read_bytes()
    rng = random.Random(20261206)
    bad, out = tmp_path / "bad.bag", tmp_path / "out.log"
    refused = 0
    for run in range(150):
        data = bytearray(original)
        kind = run % 3
        if kind == 0:  # a few bytes flipped
            for _ in range(rng.randint(1, 8)):
                data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        elif kind == 1:  # a run of bytes zeroed
            at = rng.randrange(len(data))
            n = min(rng.randint(1, 64), len(data) - at)
            data[at:at + n] = bytes(n)
        else:  # cut short
            data = data[:rng.randrange(16, len(data))]
        bad.write_bytes(bytes(data))
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            code = converter.main([str(bad), "--out", str(out), "--quiet"])
        assert code in (0, 1), (run, kind, code)
        if code == 1:
            refused += 1
            last = err.getvalue().splitlines()[-1]  # warnings (a cut-off record) may come first
            assert last.startswith("rosbag_to_carmen: error: ") and str(bad) in last, (run, kind, last)
    assert refused > 0  # the damage is seen, not only passed over


def test_a_bag_whose_name_is_not_ascii_converts_with_the_name_escaped(tmp_path):
    """The CARMEN log is ASCII: a user's "Läufer.db3" is named escaped in its first line, not a crash."""
    bag = tmp_path / "L\u00e4ufer.db3"
    tiny_bag(bag, [1.0, 1.1, 1.2], [0.9, 1.3])
    run = convert(bag, tmp_path / "out.log")
    first = (tmp_path / "out.log").read_text(encoding="ascii").splitlines()[0]
    assert "L\\xe4ufer.db3" in first, first
    assert sum(1 for line in (tmp_path / "out.log").open() if line.startswith("ROBOTLASER1")) == 3, run.stderr
