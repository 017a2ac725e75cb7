#!/usr/bin/env python3
"""Convert a ROS 2 bag (sqlite3 or MCAP) or a ROS 1 bag (format 2.0, .bag) of
laser scans and odometry into a CARMEN log (ROBOTLASER1 lines) that lshloc reads.

rosbag2's compression is undone: storage files compressed whole
(compression_mode file: NAME.db3.zstd, NAME.mcap.zstd, decompressed into a
temporary file) and messages compressed one by one (compression_mode
message); metadata.yaml says which, and a single file is recognised by its
zstd magic bytes. The laser's mount comes from /tf_static, else from /tf when
the base -> laser chain there stays fixed over the bag, else --laser-offset.

A ROS 1 bag is read record by record from its start, its chunks plain, bz2 or
lz4, without its index: a bag whose recording was cut off reads up to its last
whole record. Its sensor_msgs/LaserScan, nav_msgs/Odometry and
tf2_msgs/TFMessage (or tf/tfMessage) messages go the same way as ROS 2's.

Standard library only; zstandard (python3-zstandard) and lz4 (python3-lz4) are
imported when something is compressed with them. Messages are decoded from CDR
or ROS 1's serialization by hand, so no ROS installation is needed.
"""
import argparse
import bisect
import bz2
import collections
import gzip
import math
import mmap
import pathlib
import re
import sqlite3
import struct
import sys
import tempfile
import zlib

LASER_SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
TF_STATIC_TOPIC = "/tf_static"
TF_TOPIC = "/tf"
WANTED_TYPES = (LASER_SCAN, ODOMETRY, TF_MESSAGE)
# ROS 1 names of the wanted types; tf/tfMessage has tf2_msgs/TFMessage's layout.
ROS1_TYPES = {"sensor_msgs/LaserScan": LASER_SCAN, "nav_msgs/Odometry": ODOMETRY, "tf2_msgs/TFMessage": TF_MESSAGE,
              "tf/tfMessage": TF_MESSAGE}
# The md5sum ROS 1 gives each of those definitions, the layouts decoded here: another is another layout.
ROS1_MD5 = {"sensor_msgs/LaserScan": "90c7ef2dc6895d81024acba2ac42f369",
            "nav_msgs/Odometry": "cd5e73d190d741a2f92e81eda573aca7",
            "tf2_msgs/TFMessage": "94810edda583a504dfda3829e70d7eec",
            "tf/tfMessage": "94810edda583a504dfda3829e70d7eec"}
CDR, ROS1 = "cdr", "ros1"  # the serializations: a topic's encoding in Bag.topics

MCAP_MAGIC = b"\x89MCAP0\r\n"
SQLITE_MAGIC = b"SQLite format 3\x00"
ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
STORAGE_SUFFIXES = (".db3", ".mcap", ".db3.zstd", ".mcap.zstd")
OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x02, 0x03, 0x04, 0x05, 0x06
ROS1_PREFIX = b"#ROSBAG V"
ROS1_MAGIC = b"#ROSBAG V2.0\n"
ROS1_MESSAGE, ROS1_CHUNK, ROS1_CONNECTION = 0x02, 0x05, 0x07  # the other ops (bag header, index, chunk info): skipped

# Scans further than this outside the odometry's time span have no robot pose.
ODOMETRY_MARGIN_NS = 500_000_000
# A base -> laser transform on /tf that strays further than this from its first value is a moving laser.
MOUNT_STEADY_M = 0.001
MOUNT_STEADY_RAD = math.radians(0.1)


def one_line(text):
    """`text` with its control characters escaped: names read from a damaged bag must not break a message's line."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class BagError(Exception):
    """A problem with the input, reported as one line naming the file."""

    def __init__(self, path, what):
        super().__init__(one_line(f"{path}: {what}"))


class Progress:
    def __init__(self, quiet):
        self.quiet = quiet

    def note(self, text):
        if not self.quiet:
            print(f"rosbag_to_carmen: {text}", file=sys.stderr)


def warn(text):
    print(f"rosbag_to_carmen: warning: {one_line(text)}", file=sys.stderr)


class RawMessage:
    """One serialized message of a wanted type, with where it came from."""
    __slots__ = ("topic", "bag_ns", "data", "path")

    def __init__(self, topic, bag_ns, data, path):
        self.topic, self.bag_ns, self.data, self.path = topic, bag_ns, data, path


class Bag:
    """What the storage files hold: topic name -> (type, encoding), and the messages of the wanted types. A ROS 1
    topic of a wanted type is listed under the ROS 2 name; `bag_types` keeps the name the bag gives it."""

    def __init__(self):
        self.topics = {}
        self.bag_types = {}
        self.messages = []
        self.files = []
        self.compressed_messages = False  # metadata.yaml says compression_mode message
        self.zstd = None  # the zstd decompressor, made at the first compressed message


# ---------------------------------------------------------------- storage


def storage_files(bag_path):
    """The bag's storage files, and whether metadata.yaml says each message is compressed."""
    path = pathlib.Path(bag_path)
    if not path.exists():
        raise BagError(bag_path, "no such file or directory; expected a ROS 2 bag directory, a .db3 / .mcap file "
                       "(or one compressed as .zstd) or a ROS 1 .bag file")
    if path.is_file():
        return [path], False
    metadata = read_metadata(path / "metadata.yaml")
    compressed_messages = metadata_compression(path / "metadata.yaml", metadata)
    return listed_files(path, metadata) or found_files(path), compressed_messages


def read_metadata(path):
    """The keys of a rosbag2 metadata.yaml this script uses: relative_file_paths (a list), compression_mode and
    compression_format (strings). rosbag2 writes them in block style, one key a line; {} when there is no file."""
    if not path.is_file():
        return {}
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    metadata = {}
    for number, line in enumerate(lines):
        match = re.match(r"(\s*)(relative_file_paths|compression_mode|compression_format):\s*(.*?)\s*$", line)
        if match is None or match[2] in metadata:
            continue
        indent, key, value = len(match[1]), match[2], match[3]
        if key != "relative_file_paths":
            metadata[key] = yaml_scalar(value)
        elif value.startswith("["):
            metadata[key] = [yaml_scalar(v) for v in value.strip("[]").split(",") if v.strip()]
        else:
            metadata[key] = yaml_block_list(lines[number + 1:], indent)
    return metadata


def yaml_scalar(text):
    text = text.strip()
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "\"'":
        return text[1:-1]
    return text


def yaml_block_list(lines, key_indent):
    """The items of a block list ("- item" lines, indented at least as its key) at the start of `lines`."""
    items = []
    for line in lines:
        match = re.match(r"(\s*)-\s+(.*?)\s*$", line)
        if match is None or len(match[1]) < key_indent:
            if line.strip():
                break
            continue
        items.append(yaml_scalar(match[2]))
    return items


def metadata_compression(path, metadata):
    """Whether each message is zstd-compressed; files compressed whole are recognised by their magic bytes."""
    mode = metadata.get("compression_mode", "").lower()
    compression = metadata.get("compression_format", "")
    if mode not in ("", "none", "file", "message"):
        raise BagError(path, f"compression_mode '{mode}'; expected file, message or none")
    if mode in ("file", "message") and compression != "zstd":
        raise BagError(path, f"compression_mode {mode} with compression_format '{compression}'; expected zstd, the "
                       "format rosbag2 compresses with")
    return mode == "message"


def listed_files(directory, metadata):
    """The files metadata.yaml's relative_file_paths lists: beside it, or (rosbag2 before version 4) relative to the
    directory above; a file listed as NAME.zstd may have been decompressed to NAME."""
    files = []
    for listed in metadata.get("relative_file_paths", []):
        name = pathlib.Path(listed)
        names = (name, name.with_suffix("")) if name.suffix == ".zstd" else (name,)
        places = [place for n in names for place in (directory / n, directory.parent / n, directory / n.name)]
        found = next((place for place in places if place.is_file()), None)
        if found is None:
            raise BagError(directory / "metadata.yaml", f"relative_file_paths lists {listed}, which is not in "
                           f"{directory}; expected the bag's storage files beside metadata.yaml")
        files.append(found)
    return files


def found_files(directory):
    files = sorted(p for p in directory.iterdir() if p.is_file() and p.name.endswith(STORAGE_SUFFIXES))
    if not files:
        found = ", ".join(sorted(p.name for p in directory.iterdir())[:8]) or "nothing"
        raise BagError(directory, f"no .db3 or .mcap file (nor .db3.zstd, .mcap.zstd) in the directory (found "
                       f"{found}); expected a ROS 2 bag directory (metadata.yaml and its storage files)")
    return files


def read_bag(bag_path, progress):
    bag = Bag()
    files, bag.compressed_messages = storage_files(bag_path)
    for path in files:
        progress.note(f"reading {path}")
        read_storage_file(path, bag, progress)
        bag.files.append(path)
    # Storage order need not be time order (MCAP chunks, several files).
    bag.messages.sort(key=lambda m: m.bag_ns)
    return bag


def first_bytes(path, count=16):
    with open(path, "rb") as f:
        return f.read(count)


def read_storage_file(path, bag, progress):
    """Reads one storage file; one compressed whole (compression_mode file) through a temporary copy."""
    start = first_bytes(path)
    if start.startswith(ZSTD_MAGIC):
        with tempfile.TemporaryDirectory(prefix="rosbag_to_carmen-") as scratch:
            plain = pathlib.Path(scratch) / (path.name[:-len(".zstd")] if path.name.endswith(".zstd") else "bag")
            size = decompress_file(path, plain)
            progress.note(f"decompressed {path} to {size} bytes in {plain}")
            read_plain_storage(plain, bag, path, "decompressed, ")
    elif path.name.endswith(".zstd"):
        raise BagError(path, f"begins {start[:4].hex(' ') or 'empty'}, not a zstd frame; expected a zstd-compressed "
                       "ROS 2 storage file (zstd frames begin 28 b5 2f fd)")
    else:
        read_plain_storage(path, bag, path)


def read_plain_storage(file, bag, name, what=""):
    """Reads `file`; errors and messages name `name`, the file as the bag holds it."""
    start = first_bytes(file)
    if start.startswith(MCAP_MAGIC):
        read_mcap(file, bag, name)
    elif start == SQLITE_MAGIC:
        read_sqlite(file, bag, name)
    elif start.startswith(ROS1_PREFIX):
        read_ros1(file, bag, name)
    else:
        raise BagError(name, f"{what}neither a sqlite3 database nor an MCAP file nor a ROS 1 bag (by its first "
                       "bytes); expected a ROS 2 bag's .db3 or .mcap storage file or a ROS 1 .bag file")


def lz4_decompress(data, path, where):
    """One LZ4 frame (MCAP's and ROS 1's lz4 chunks), lz4 (python3-lz4) imported only then."""
    try:
        import lz4.frame
    except ImportError:
        raise BagError(path, f"{where} is lz4-compressed and the Python module lz4 is missing; expected it "
                       "installed (apt install python3-lz4)") from None
    try:
        return lz4.frame.decompress(data)
    except RuntimeError as e:
        raise BagError(path, f"{where}: lz4 says {e}; expected a valid LZ4 frame") from None


def zstandard_module(path, what):
    try:
        import zstandard
    except ImportError:
        raise BagError(path, f"{what} and the Python module zstandard is missing; expected it installed "
                       "(apt install python3-zstandard)") from None
    return zstandard


def decompress_file(path, out_path):
    """Decompresses the zstd frames of `path` into `out_path` by streaming (frames need not hold their size)."""
    zstandard = zstandard_module(path, "is zstd-compressed")
    decompressor = zstandard.ZstdDecompressor()
    size, inside_frame = 0, False
    with open(path, "rb") as source, open(out_path, "wb") as out:
        frame = decompressor.decompressobj()
        while data := source.read(1 << 20):
            while data:
                try:
                    plain = frame.decompress(data)
                except zstandard.ZstdError as e:
                    raise BagError(path, f"zstd says {e} (after {size} bytes decompressed); expected a valid zstd "
                                   "frame (a damaged file?)") from None
                out.write(plain)
                size += len(plain)
                inside_frame, data = not frame.eof, b""
                if frame.eof:  # another frame may follow
                    data, frame = frame.unused_data, decompressor.decompressobj()
    if inside_frame:
        raise BagError(path, f"ends inside a zstd frame (after {size} bytes decompressed); expected whole zstd "
                       "frames (a truncated file, or one still being compressed?)")
    return size


def read_sqlite(file, bag, path):
    """Reads the database `file`; errors and messages name `path`."""
    try:
        db = sqlite3.connect(file.resolve().as_uri() + "?mode=ro", uri=True)
    except sqlite3.Error as e:
        raise BagError(path, f"cannot open the sqlite3 database ({e})") from None
    # Damaged text (not UTF-8) reads with replacement characters, to be refused by name below.
    db.text_factory = lambda raw: raw.decode("utf-8", errors="replace")
    try:
        ids = {}
        for topic_id, name, type_name, encoding in db.execute(
                "SELECT id, name, type, serialization_format FROM topics"):
            if not all(isinstance(v, str) for v in (name, type_name, encoding)):
                raise BagError(path, f"topic id {topic_id!r}: name {name!r}, type {type_name!r}, serialization "
                               f"{encoding!r}; expected text in each column of the topics table")
            bag.topics[name] = (type_name, encoding)
            if type_name in WANTED_TYPES:
                ids[topic_id] = name
        rows = db.execute("SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id")
        for topic_id, stamp, data in rows:
            if topic_id in ids:
                if not isinstance(stamp, int) or not isinstance(data, bytes):
                    raise BagError(path, f"a message on {ids[topic_id]} has timestamp {stamp!r} and data of type "
                                   f"{type(data).__name__}; expected an integer [ns] and a blob in the messages table")
                bag.messages.append(RawMessage(ids[topic_id], stamp, data, path))
    except (sqlite3.Error, UnicodeDecodeError) as e:  # a damaged schema's column names are no UTF-8
        raise BagError(path, f"not a readable rosbag2 database ({e}); expected the tables topics(id, name, type, "
                       "serialization_format) and messages(topic_id, timestamp, data)") from None
    finally:
        db.close()


class McapRecords:
    """Walks opcode + u64 length + content records between two offsets; `where` prefixes the offsets in errors."""

    def __init__(self, buf, start, end, path, where):
        self.buf, self.pos, self.end, self.path, self.where = buf, start, end, path, where

    def __iter__(self):
        while self.pos < self.end:
            at = self.pos
            if self.end - at < 9:
                raise BagError(self.path, f"{self.where} byte {at}: a record header needs 9 bytes, {self.end - at} "
                               "left; expected opcode and length (a truncated file?)")
            opcode, length = struct.unpack_from("<BQ", self.buf, at)
            content = at + 9
            if length > self.end - content:
                raise BagError(self.path, f"{self.where} byte {at}: record opcode 0x{opcode:02x} claims {length} "
                               f"bytes, {self.end - content} left; expected a whole record (a truncated file?)")
            self.pos = content + length
            yield opcode, at, McapFields(self.buf, content, self.pos, self.path, f"{self.where} byte {at}", opcode)


class McapFields:
    """Reads the fields of one MCAP record's content."""

    def __init__(self, buf, start, end, path, where, opcode):
        self.buf, self.pos, self.end, self.path, self.where, self.opcode = buf, start, end, path, where, opcode

    def _take(self, fmt):
        size = struct.calcsize(fmt)
        if self.pos + size > self.end:
            raise BagError(self.path, f"{self.where}: record opcode 0x{self.opcode:02x} ends early; expected its "
                           "fields as the MCAP spec lists them")
        values = struct.unpack_from(fmt, self.buf, self.pos)
        self.pos += size
        return values[0] if len(values) == 1 else values

    def u16(self):
        return self._take("<H")

    def u32(self):
        return self._take("<I")

    def u64(self):
        return self._take("<Q")

    def blob(self, length):
        if self.pos + length > self.end:
            raise BagError(self.path, f"{self.where}: record opcode 0x{self.opcode:02x} holds a field of {length} "
                           f"bytes, {self.end - self.pos} left; expected its fields as the MCAP spec lists them")
        data = bytes(self.buf[self.pos:self.pos + length])
        self.pos += length
        return data

    def string(self):
        return self.blob(self.u32()).decode("utf-8", errors="replace")

    def rest(self):
        return self.blob(self.end - self.pos)


def read_mcap(file, bag, path):
    """Reads the MCAP file `file`; errors and messages name `path`."""
    size = file.stat().st_size
    if size < 2 * len(MCAP_MAGIC):
        raise BagError(path, f"{size} bytes; expected an MCAP file with a header, records and a footer")
    with open(file, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        state = McapState(path, bag)
        records = McapRecords(buf, len(MCAP_MAGIC), size, path, "at")
        for opcode, at, fields in records:
            if opcode == OP_FOOTER:
                if buf[records.pos:records.pos + len(MCAP_MAGIC)] != MCAP_MAGIC:
                    raise BagError(path, f"byte {records.pos}: no closing magic after the footer; expected "
                                   "\\x89MCAP0\\r\\n")
                return
            if opcode == OP_CHUNK:
                state.read_chunk(fields, at)
            else:
                state.read_record(opcode, fields)
        raise BagError(path, f"ends at byte {size} without a footer record; expected a complete MCAP file "
                       "(a truncated or still-recording bag?)")


class McapState:
    def __init__(self, path, bag):
        self.path, self.bag = path, bag
        self.schemas = {}
        self.channels = {}

    def read_record(self, opcode, fields):
        if opcode == OP_SCHEMA:
            schema_id, name = fields.u16(), fields.string()
            self.schemas[schema_id] = name
        elif opcode == OP_CHANNEL:
            channel_id, schema_id, topic, encoding = fields.u16(), fields.u16(), fields.string(), fields.string()
            type_name = self.schemas.get(schema_id, "")
            self.channels[channel_id] = (topic, type_name)
            self.bag.topics[topic] = (type_name, encoding)
        elif opcode == OP_MESSAGE:
            channel_id = fields.u16()
            fields.blob(4)  # sequence number
            log_time = fields.u64()
            fields.blob(8)  # publish time: the bag's time is the log (receive) time
            channel = self.channels.get(channel_id)
            if channel is None:
                raise BagError(self.path, f"{fields.where}: a message on channel {channel_id}, which no channel "
                               "record defined before it; expected channels before their messages")
            if channel[1] in WANTED_TYPES:
                self.bag.messages.append(RawMessage(channel[0], log_time, fields.rest(), self.path))

    def read_chunk(self, fields, at):
        fields.blob(16)  # message start and end times: every message carries its own
        uncompressed_size, crc = fields.u64(), fields.u32()
        compression = fields.string()
        data = fields.blob(fields.u64())
        records = decompress(data, compression, uncompressed_size, self.path, at)
        if len(records) != uncompressed_size:
            raise BagError(self.path, f"chunk at byte {at}: {len(records)} bytes uncompressed; expected "
                           f"{uncompressed_size} (a damaged chunk?)")
        if crc != 0 and zlib.crc32(records) != crc:
            raise BagError(self.path, f"chunk at byte {at}: CRC mismatch of its records; expected 0x{crc:08x} "
                           "(a damaged chunk?)")
        for opcode, _, inner in McapRecords(records, 0, len(records), self.path, f"chunk at byte {at}, record at"):
            self.read_record(opcode, inner)


def decompress(data, compression, uncompressed_size, path, at):
    if compression == "":
        return data
    if compression == "zstd":
        zstandard = zstandard_module(path, f"chunk at byte {at} is zstd-compressed")
        try:
            return zstandard.ZstdDecompressor().decompress(data, max_output_size=uncompressed_size)
        except zstandard.ZstdError as e:
            raise BagError(path, f"chunk at byte {at}: zstd says {e}; expected a valid zstd frame") from None
    if compression == "lz4":
        return lz4_decompress(data, path, f"chunk at byte {at}")
    raise BagError(path, f"chunk at byte {at} uses compression '{compression}'; expected none, zstd or lz4")


# ---------------------------------------------------------------- ROS 1 bags

ROS1_OPS = {0x02: "message data", 0x03: "bag header", 0x04: "index data", 0x05: "chunk", 0x06: "chunk info",
            0x07: "connection"}


def read_ros1(file, bag, path):
    """Reads the ROS 1 bag `file` record by record from its start, not through its index (which a bag whose
    recording was cut off lacks); errors and warnings name `path`."""
    with open(file, "rb") as f:
        line = f.readline(64)
    if line != ROS1_MAGIC:
        head = line.split(b"\n")[0][:16]  # a damaged line may run on into binary records

        def shown(text):
            return repr(text)[2:-1]  # bytes as Python writes them: escapes, no raw control bytes

        raise BagError(path, f"begins '{shown(head)}', a ROS 1 bag of format {shown(head[len(ROS1_PREFIX):]) or '?'}; "
                       "expected format 2.0 ('#ROSBAG V2.0'), the only one read")
    with open(file, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        state = Ros1State(path, bag)
        for at, fields, data in ros1_records(buf, len(ROS1_MAGIC), len(buf), path, "record at", cut_off_ok=True):
            state.read_record(fields, buf, data, at, f"record at byte {at}")


def ros1_records(buf, start, end, path, where, cut_off_ok):
    """The records (offset, header fields, (start, end) of the data) between two offsets of `buf`: header length,
    header, data length, data. A record running past `end` is an error, or with `cut_off_ok` (the file's last
    record, from a recording cut off) a warning that ends the walk."""
    pos = start
    while pos < end:
        at = pos
        data_at = at + 4 + (struct.unpack_from("<I", buf, at)[0] if end - at >= 4 else end)
        data_len = struct.unpack_from("<I", buf, data_at)[0] if end - data_at >= 4 else end
        pos = data_at + 4 + data_len
        if pos > end:
            if not cut_off_ok:
                raise BagError(path, f"{where} byte {at}: a record runs past the end ({end - at} bytes left); "
                               "expected whole records, each header length, header, data length and data")
            warn(f"{path}: the file ends inside the record at byte {at} ({end - at} bytes of it there); read the "
                 "records before it (a bag whose recording was cut off?)")
            return
        # The data as offsets: copied only when read (a bag's camera images need not be).
        yield at, ros1_fields(buf, at + 4, data_at, path, f"{where} byte {at}"), (data_at + 4, pos)


def ros1_fields(buf, start, end, path, where):
    """A ROS 1 header between two offsets: fields of u32 length then name=value, as name -> the value's bytes."""
    fields = {}
    pos = start
    while pos < end:
        length = struct.unpack_from("<I", buf, pos)[0] if end - pos >= 4 else end
        if length > end - pos - 4:
            raise BagError(path, f"{where}: a header field at byte {pos} runs past the header's end ({end - pos} "
                           "bytes left); expected fields of u32 length then name=value")
        name, equals, value = bytes(buf[pos + 4:pos + 4 + length]).partition(b"=")
        if not equals:
            raise BagError(path, f"{where}: the header field at byte {pos} has no '='; expected name=value")
        fields.setdefault(name.decode("ascii", errors="replace"), value)
        pos += 4 + length
    return fields


class Ros1State:
    """The connections (id -> topic, type) seen so far in a ROS 1 bag."""

    def __init__(self, path, bag):
        self.path, self.bag = path, bag
        self.connections = {}

    def field(self, fields, name, fmt, op, where):
        value = fields.get(name)
        size = struct.calcsize(fmt)
        if value is None or len(value) != size:
            held = "no" if value is None else f"a {len(value)}-byte"
            record = f"the {ROS1_OPS[op]} record" if op in ROS1_OPS else "the record"
            raise BagError(self.path, f"{where}: {record} has {held} field '{name}'; expected a {size}-byte {name} "
                           "(format 2.0)")
        values = struct.unpack(fmt, value)
        return values[0] if len(values) == 1 else values

    def read_record(self, fields, buf, data, at, where):
        """Reads one record, its data between the offsets `data` of `buf`."""
        op = self.field(fields, "op", "<B", None, where)
        if op == ROS1_CHUNK:
            self.read_chunk(fields, buf[data[0]:data[1]], at, where)
        elif op == ROS1_CONNECTION:
            conn = self.field(fields, "conn", "<I", op, where)
            if conn in self.connections:
                return  # the index section repeats the chunks' connection records
            described = ros1_fields(buf, *data, self.path, f"{where}: connection {conn}'s connection header")
            topic = fields.get("topic", described.get("topic", b"")).decode("utf-8", errors="replace")
            bag_type = described.get("type", b"").decode("utf-8", errors="replace")
            if not topic or not bag_type:
                raise BagError(self.path, f"{where}: connection {conn} has no {'topic' if bag_type else 'type'}; "
                               "expected topic and type fields in its connection record")
            type_name = ROS1_TYPES.get(bag_type, bag_type)
            md5 = described.get("md5sum", b"").decode("ascii", errors="replace")
            if bag_type in ROS1_MD5 and md5 not in ("", "*", ROS1_MD5[bag_type]):
                raise BagError(self.path, f"{where}: topic {topic} is {bag_type} with md5sum {md5}; expected "
                               f"{ROS1_MD5[bag_type]}, the standard definition (this one's fields differ)")
            self.connections[conn] = (topic, type_name)
            if topic not in self.bag.topics:  # a topic's first type is the one read
                self.bag.topics[topic] = (type_name, ROS1)
                self.bag.bag_types[topic] = bag_type
        elif op == ROS1_MESSAGE:
            conn = self.field(fields, "conn", "<I", op, where)
            sec, nsec = self.field(fields, "time", "<II", op, where)
            connection = self.connections.get(conn)
            if connection is None:
                raise BagError(self.path, f"{where}: a message on connection {conn}, which no connection record "
                               "defined before it; expected connections before their messages")
            topic, type_name = connection
            if type_name in WANTED_TYPES and self.bag.topics[topic][0] == type_name:
                self.bag.messages.append(RawMessage(topic, sec * 1_000_000_000 + nsec, buf[data[0]:data[1]],
                                                    self.path))

    def read_chunk(self, fields, data, at, where):
        compression = fields.get("compression", b"").decode("ascii", errors="replace")
        size = self.field(fields, "size", "<I", ROS1_CHUNK, where)
        records = ros1_decompress(data, compression, self.path, f"chunk at byte {at}")
        if len(records) != size:
            raise BagError(self.path, f"chunk at byte {at}: {len(records)} bytes uncompressed; expected {size}, its "
                           "size field (a damaged chunk?)")
        chunk = f"chunk at byte {at}, record at"
        for inner_at, inner, inner_data in ros1_records(records, 0, size, self.path, chunk, cut_off_ok=False):
            self.read_record(inner, records, inner_data, inner_at, f"{chunk} byte {inner_at}")


def ros1_decompress(data, compression, path, where):
    if compression == "none":
        return data
    if compression == "bz2":
        try:
            return bz2.decompress(data)
        except (OSError, ValueError, EOFError) as e:
            raise BagError(path, f"{where}: bz2 says {e}; expected a valid bz2 stream") from None
    if compression == "lz4":
        return lz4_decompress(data, path, where)
    raise BagError(path, f"{where} uses compression '{compression}'; expected none, bz2 or lz4")


# ---------------------------------------------------------------- CDR and ROS 1 serialization


class MessageError(Exception):
    """A message its serialization does not describe."""


class MessageEndsEarly(MessageError):
    """A message shorter than its fields."""


class MessageReader:
    """Reads primitives in byte order `order` from byte `pos` of `data`, each after `_pad` bytes of padding."""

    def __init__(self, data, order, pos):
        self.data, self.order, self.pos = data, order, pos

    def _pad(self, size):
        return 0

    def _take(self, code, size, count):
        self.pos += self._pad(size)
        end = self.pos + size * count
        if end > len(self.data):
            raise MessageEndsEarly(f"{len(self.data)} bytes, a field at byte {self.pos} needs {end}")
        values = struct.unpack_from(f"{self.order}{count}{code}", self.data, self.pos)
        self.pos = end
        return values

    def i32(self):
        return self._take("i", 4, 1)[0]

    def u32(self):
        return self._take("I", 4, 1)[0]

    def f32s(self, count):
        return self._take("f", 4, count)

    def f64s(self, count):
        return self._take("d", 8, count)

    def string(self):
        length = self.u32()
        if self.pos + length > len(self.data):
            raise MessageEndsEarly(f"{len(self.data)} bytes, a string at byte {self.pos} needs {self.pos + length}")
        text = self.data[self.pos:self.pos + length].rstrip(b"\0")
        self.pos += length
        return text.decode("utf-8", errors="replace")


class CdrReader(MessageReader):
    """Plain CDR (XCDR1): each primitive aligned to its size, counted from the end of the 4-byte header."""

    def __init__(self, data):
        if len(data) < 4:
            raise MessageEndsEarly(f"{len(data)} bytes, less than the 4-byte encapsulation header")
        if data[0] != 0 or data[1] not in (0, 1):
            raise MessageError(f"encapsulation header {data[0]:02x} {data[1]:02x}; expected plain CDR "
                               "(00 01 little-endian or 00 00 big-endian)")
        super().__init__(data, "<" if data[1] == 1 else ">", 4)

    def _pad(self, size):
        return -(self.pos - 4) % size

    def header(self):
        sec, nanosec = self.i32(), self.u32()
        return sec * 1_000_000_000 + nanosec, self.string()


class Ros1Reader(MessageReader):
    """ROS 1's serialization: little-endian and packed, no header; times are u32 sec, u32 nsec."""

    def __init__(self, data):
        super().__init__(data, "<", 0)

    def header(self):
        self.u32()  # seq: a counter of no use here
        sec, nanosec = self.u32(), self.u32()
        return sec * 1_000_000_000 + nanosec, self.string()


READERS = {CDR: CdrReader, ROS1: Ros1Reader}
SERIALIZED = {CDR: "CDR-encoded", ROS1: "ROS 1-serialized"}


class Scan:
    __slots__ = ("stamp_ns", "bag_ns", "frame", "angle_min", "angle_increment", "range_min", "range_max", "ranges")


def decode_scan(reader):
    scan = Scan()
    scan.stamp_ns, scan.frame = reader.header()
    angle_min, _angle_max, scan.angle_increment, _time_increment, _scan_time, scan.range_min, scan.range_max = \
        reader.f32s(7)
    scan.angle_min = angle_min
    scan.ranges = reader.f32s(reader.u32())
    reader.f32s(reader.u32())  # intensities: read only to check the message is whole
    return scan


class Odometry:
    __slots__ = ("stamp_ns", "bag_ns", "child_frame", "x", "y", "yaw")


def decode_odometry(reader):
    odom = Odometry()
    odom.stamp_ns, _frame = reader.header()
    odom.child_frame = reader.string()
    odom.x, odom.y, _z, qx, qy, qz, qw = reader.f64s(7)
    odom.yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    reader.f64s(36 + 6 + 36)  # pose covariance, twist and its covariance: read only to check the message is whole
    return odom


def decode_tf(reader):
    transforms = []
    for _ in range(reader.u32()):
        _stamp, parent = reader.header()
        child = reader.string()
        translation = reader.f64s(3)
        rotation = reader.f64s(4)
        transforms.append((parent.lstrip("/"), child.lstrip("/"), Transform.from_ros(translation, rotation)))
    return transforms


DECODERS = {LASER_SCAN: decode_scan, ODOMETRY: decode_odometry, TF_MESSAGE: decode_tf}


def decode_topic(bag, topic, type_name):
    """Decodes every message of one topic; errors name the file, topic and message number."""
    decoded = []
    encoding = bag.topics[topic][1]
    reader = READERS.get(encoding)
    for number, msg in enumerate((m for m in bag.messages if m.topic == topic), start=1):
        if reader is None:
            raise BagError(msg.path, f"topic {topic} is serialized as '{encoding}'; expected 'cdr' (ROS 2's default)")
        where = f"message {number} on topic {topic}"
        try:
            value = DECODERS[type_name](reader(msg.data if encoding == ROS1 else message_bytes(bag, msg, where)))
        except MessageEndsEarly as e:
            raise BagError(msg.path, f"{where} ends early ({e}); expected a complete {SERIALIZED[encoding]} "
                           f"{bag.bag_types.get(topic, type_name)}") from None
        except MessageError as e:
            raise BagError(msg.path, f"message {number} on topic {topic}: {e}") from None
        if type_name != TF_MESSAGE:
            value.bag_ns = msg.bag_ns
        decoded.append(value)
    return decoded


def message_bytes(bag, msg, where):
    """A ROS 2 message's serialized bytes, decompressed when rosbag2 compressed it alone (compression_mode message).
    CDR begins with a 00 byte, so a zstd frame's magic tells the two apart without metadata.yaml."""
    if not msg.data.startswith(ZSTD_MAGIC):
        if bag.compressed_messages:
            raise BagError(msg.path, f"{where} begins {msg.data[:4].hex(' ') or 'empty'}, not a zstd frame; "
                           "expected each message zstd-compressed, as metadata.yaml says compression_mode message")
        return msg.data
    zstandard = zstandard_module(msg.path, f"{where} is zstd-compressed")
    if bag.zstd is None:
        bag.zstd = zstandard.ZstdDecompressor()
    frame = bag.zstd.decompressobj()  # streaming: the frame need not hold its size
    try:
        data = frame.decompress(msg.data)
    except zstandard.ZstdError as e:
        raise BagError(msg.path, f"{where}: zstd says {e}; expected a valid zstd frame") from None
    if not frame.eof:
        raise BagError(msg.path, f"{where} ends inside its zstd frame; expected a whole frame (a damaged message?)")
    return data


# ---------------------------------------------------------------- geometry


class Transform:
    """A 3D rigid transform: rotation matrix rows and translation."""

    def __init__(self, rotation, translation):
        self.r, self.t = rotation, translation

    @staticmethod
    def from_ros(translation, quaternion):
        x, y, z, w = quaternion
        norm = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
        x, y, z, w = x / norm, y / norm, z / norm, w / norm
        rotation = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                    [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                    [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
        return Transform(rotation, list(translation))

    def then(self, other):
        """This transform followed by `other`, expressed in this one's parent frame."""
        r = [[sum(self.r[i][k] * other.r[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
        t = [sum(self.r[i][k] * other.t[k] for k in range(3)) + self.t[i] for i in range(3)]
        return Transform(r, t)

    def inverse(self):
        r = [[self.r[j][i] for j in range(3)] for i in range(3)]
        t = [-sum(r[i][k] * self.t[k] for k in range(3)) for i in range(3)]
        return Transform(r, t)


IDENTITY = Transform([[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0, 0, 0])


def tf_history(bag, topic):
    """Each edge (parent, child) of a tf topic -> [(message number, Transform)] in bag order; {} without it."""
    history = {}
    if bag.topics.get(topic, ("",))[0] == TF_MESSAGE:
        for number, message in enumerate(decode_topic(bag, topic, TF_MESSAGE), start=1):
            for parent, child, transform in message:
                history.setdefault((parent, child), []).append((number, transform))
    return history


def tf_path(edges, base, target):
    """The edges (parent, child) from `base` to `target` through the tree of `edges`, each with whether it is
    walked from parent to child; None when no path links them."""
    neighbours = {}
    for parent, child in edges:
        neighbours.setdefault(parent, {})[child] = ((parent, child), True)
        neighbours.setdefault(child, {})[parent] = ((parent, child), False)
    came_from = {base: None}
    queue = collections.deque([base])
    while queue:
        frame = queue.popleft()
        if frame == target:
            steps = []
            while came_from[frame] is not None:
                frame, edge, forward = came_from[frame]
                steps.append((edge, forward))
            return steps[::-1]
        for neighbour, (edge, forward) in neighbours.get(frame, {}).items():
            if neighbour not in came_from:
                came_from[neighbour] = (frame, edge, forward)
                queue.append(neighbour)
    return None


def compose_path(steps, transforms):
    """The pose of a path's last frame in its first: its transforms chained, those walked backwards inverted."""
    pose = IDENTITY
    for edge, forward in steps:
        pose = pose.then(transforms[edge] if forward else transforms[edge].inverse())
    return pose


def rotation_angle(a, b):
    """The angle [rad] of the rotation between the orientations of transforms a and b."""
    trace = sum(a.r[i][j] * b.r[i][j] for i in range(3) for j in range(3))
    return math.acos(max(-1.0, min(1.0, (trace - 1.0) / 2.0)))


def steady_transform(bag_path, edge, history, base_frame, laser_frame):
    """The first of an edge's /tf transforms, when none of the others strays from it further than a fixed mount's
    tolerance (1 mm, 0.1 degrees)."""
    first_number, first = history[0]
    for number, transform in history[1:]:
        shift = math.dist(first.t, transform.t)
        turn = rotation_angle(first, transform)
        if shift > MOUNT_STEADY_M or turn > MOUNT_STEADY_RAD:
            raise BagError(bag_path, f"{TF_TOPIC} message {number}: {edge[0]} -> {edge[1]}, on the chain from "
                           f"'{base_frame}' to the laser frame '{laser_frame}', is {shift * 1000:.1f} mm and "
                           f"{math.degrees(turn):.2f} degrees from its value in message {first_number}: the laser "
                           "moves relative to the base; expected a fixed mount (give it with --laser-offset "
                           "X,Y,THETA)")
    return first


def wrap(angle):
    return math.atan2(math.sin(angle), math.cos(angle))


class Mount:
    """The laser's planar pose on the robot; `upside_down` lasers sweep the other way seen from above. `topics`:
    the tf topics it came from."""

    def __init__(self, x, y, theta, upside_down, source, topics=()):
        self.x, self.y, self.theta, self.upside_down, self.source = x, y, theta, upside_down, source
        self.topics = topics

    @staticmethod
    def from_transform(transform, source, topics):
        r = transform.r
        # The yaw of where the laser's x-axis points; its z-axis pointing down means a flipped sweep.
        return Mount(transform.t[0], transform.t[1], math.atan2(r[1][0], r[0][0]), r[2][2] < 0.0, source, topics)


def laser_mount(args, static, read_tf, base_frame, laser_frame):
    """The mount from --laser-offset, else the chain base -> laser in /tf_static, else that chain with the edges
    /tf_static lacks taken from /tf (`read_tf()` decodes it: only read when needed), else (0, 0, 0)."""
    if args.laser_offset is not None:
        return Mount(*args.laser_offset, False, "--laser-offset")
    fixed = {edge: values[-1][1] for edge, values in static.items()}  # of repeated static transforms the last wins
    steps = tf_path(fixed, base_frame, laser_frame)
    if steps is not None:
        return Mount.from_transform(compose_path(steps, fixed), f"{TF_STATIC_TOPIC} {base_frame} -> {laser_frame}",
                                    (TF_STATIC_TOPIC,))
    moving = read_tf()
    steps = tf_path([*fixed, *(edge for edge in moving if edge not in fixed)], base_frame, laser_frame)
    if steps is None:
        if not fixed and not moving:
            warn(f"no {TF_STATIC_TOPIC} transforms and no --laser-offset (nor {TF_TOPIC} ones): the laser is taken "
                 "to sit at the robot's origin (0, 0, 0)")
        else:
            frames = sorted({frame for edge in (*fixed, *moving) for frame in edge})
            warn(f"neither {TF_STATIC_TOPIC} nor {TF_TOPIC} links a path from '{base_frame}' to the laser frame "
                 f"'{laser_frame}' (frames: {', '.join(frames)}); the laser is taken to sit at the robot's origin "
                 "(0, 0, 0): give --base-frame or --laser-offset")
        return Mount(0.0, 0.0, 0.0, False, "nowhere (assumed 0, 0, 0)")
    from_static = any(edge in fixed for edge, _ in steps)
    for edge, _ in steps:
        if edge not in fixed:
            fixed[edge] = steady_transform(args.bag, edge, moving[edge], base_frame, laser_frame)
    topics = (TF_STATIC_TOPIC, TF_TOPIC) if from_static else (TF_TOPIC,)
    return Mount.from_transform(compose_path(steps, fixed), f"{' and '.join(topics)} {base_frame} -> {laser_frame}",
                                topics)


class OdometryTrack:
    """Robot poses by time, interpolated linearly; the heading along the shorter way round."""

    def __init__(self, readings, stamp_of):
        by_time = {}
        for odom in readings:
            by_time[stamp_of(odom)] = odom  # of equal stamps the last wins
        self.times = sorted(by_time)
        self.poses = [(by_time[t].x, by_time[t].y, by_time[t].yaw) for t in self.times]

    def pose_at(self, t):
        """The pose at time t [ns], or None further than the margin outside the track."""
        times = self.times
        if t < times[0] - ODOMETRY_MARGIN_NS or t > times[-1] + ODOMETRY_MARGIN_NS:
            return None
        i = bisect.bisect_left(times, t)
        if i < len(times) and times[i] == t:
            return self.poses[i]
        if i == 0:
            return self.poses[0]
        if i == len(times):
            return self.poses[-1]
        (x0, y0, a0), (x1, y1, a1) = self.poses[i - 1], self.poses[i]
        f = (t - times[i - 1]) / (times[i] - times[i - 1])
        return x0 + f * (x1 - x0), y0 + f * (y1 - y0), wrap(a0 + f * wrap(a1 - a0))


# ---------------------------------------------------------------- output


def stamp_text(ns):
    sign = "-" if ns < 0 else ""
    sec, frac = divmod(abs(ns), 1_000_000_000)
    return f"{sign}{sec}.{frac:09d}"


def range_fields(scan, max_range_text):
    """ROS ranges as lshloc reads them: no return (+inf, > range_max) as max_range, invalid beams (NaN, -inf,
    < range_min) as nan."""
    out = []
    for r in scan.ranges:
        if r != r or r < scan.range_min:
            out.append("nan")
        elif r > scan.range_max:
            out.append(max_range_text)
        else:
            out.append("%.9g" % r)
    return out


def robotlaser_line(scan, robot, mount, stamp_ns):
    ranges = range_fields(scan, "%.17g" % scan.range_max)
    angle_min = scan.angle_min
    n = len(ranges)
    if mount.upside_down:
        ranges.reverse()
        angle_min = -(scan.angle_min + (n - 1) * scan.angle_increment)
    fov = abs(scan.angle_increment) * max(n - 1, 1)
    rx, ry, rt = robot
    c, s = math.cos(rt), math.sin(rt)
    laser = (rx + c * mount.x - s * mount.y, ry + s * mount.x + c * mount.y, wrap(rt + mount.theta))
    stamp = stamp_text(stamp_ns)
    # Exact float32 values in %.17g: max_range must compare equal to the no-return ranges written as it.
    return " ".join([
        "ROBOTLASER1 0", "%.17g" % angle_min, "%.17g" % fov, "%.17g" % scan.angle_increment,
        "%.17g" % scan.range_max, "0.01 0", str(n), *ranges, "0",
        "%.9f %.9f %.9f" % laser, "%.9f %.9f %.9f" % robot, "0 0 0 0 0", stamp, "rosbag", stamp])


def choose_topic(bag, bag_path, type_name, option, requested):
    candidates = sorted(t for t, (ty, _) in bag.topics.items() if ty == type_name)
    if requested is not None:
        if requested not in bag.topics:
            raise BagError(bag_path, f"no topic {requested} ({option}); expected one of "
                           f"{', '.join(sorted(bag.topics)) or 'none'}")
        if bag.topics[requested][0] != type_name:
            found = bag.bag_types.get(requested, bag.topics[requested][0])
            raise BagError(bag_path, f"topic {requested} ({option}) is a {found}; expected a {type_name}")
        return requested
    if len(candidates) == 1:
        return candidates[0]
    if not candidates:
        return None
    raise BagError(bag_path, f"{len(candidates)} {type_name} topics ({', '.join(candidates)}); expected one, "
                   f"or the one to use named with {option}")


def open_output(path):
    if str(path).endswith(".gz"):
        return gzip.open(path, "wt", encoding="ascii")
    return open(path, "w", encoding="ascii")


def convert(args):
    progress = Progress(args.quiet)
    bag = read_bag(args.bag, progress)
    progress.note(f"read {len(bag.messages)} scan, odometry and tf messages from {len(bag.files)} file(s)")

    scan_topic = choose_topic(bag, args.bag, LASER_SCAN, "--scan-topic", args.scan_topic)
    if scan_topic is None:
        listed = ", ".join(f"{t} ({bag.bag_types.get(t, ty)})" for t, (ty, _) in sorted(bag.topics.items())) \
            or "no topics"
        raise BagError(args.bag, f"no {LASER_SCAN} topic (found {listed}); expected a bag with laser scans")
    odom_topic = choose_topic(bag, args.bag, ODOMETRY, "--odom-topic", args.odom_topic)

    scans = decode_topic(bag, scan_topic, LASER_SCAN)
    if not scans:
        raise BagError(args.bag, f"topic {scan_topic} holds no message; expected laser scans")
    odometry = decode_topic(bag, odom_topic, ODOMETRY) if odom_topic else []
    static = tf_history(bag, TF_STATIC_TOPIC)
    progress.note(f"decoded {len(scans)} scans on {scan_topic}, {len(odometry)} odometry messages on "
                  f"{odom_topic or '(none)'}, {sum(map(len, static.values()))} static transforms")

    base_frame = args.base_frame or (odometry[0].child_frame.lstrip("/") if odometry else "") or "base_link"
    mount = laser_mount(args, static, lambda: tf_history(bag, TF_TOPIC), base_frame, scans[0].frame.lstrip("/"))

    def stamp_of(message):
        return message.stamp_ns if args.stamp == "header" else message.bag_ns

    track = OdometryTrack(odometry, stamp_of) if odometry else None
    if track is None:
        warn(f"no {ODOMETRY} topic: writing zero odometry; localize the log with `lshloc localize --no-odometry`")
    header = (f"# converted by rosbag_to_carmen.py from {args.bag} (topics {scan_topic}, {odom_topic or 'no odometry'}"
              f"{''.join(', ' + topic for topic in mount.topics)})")
    # The log is ASCII: a bag path or topic outside it (a user's "Läufer.bag") is written escaped.
    lines = [header.encode("ascii", "backslashreplace").decode("ascii")]
    dropped = 0
    for scan in scans:
        stamp = stamp_of(scan)
        robot = track.pose_at(stamp) if track else (0.0, 0.0, 0.0)
        if robot is None:
            dropped += 1
            continue
        lines.append(robotlaser_line(scan, robot, mount, stamp))

    try:
        with open_output(args.out) as out:
            out.write("\n".join(lines) + "\n")
    except OSError as e:
        raise BagError(args.out, f"cannot write the log ({e.strerror}); expected a writable path") from None

    print(f"rosbag_to_carmen: wrote {len(lines) - 1} scans to {args.out} (read {len(bag.messages)} messages; "
          f"scans {scan_topic}, odometry {odom_topic or 'none'}, stamps from the {args.stamp})", file=sys.stderr)
    if dropped:
        print(f"rosbag_to_carmen: dropped {dropped} scans more than {ODOMETRY_MARGIN_NS / 1e9:g} s outside the "
              "odometry's time span", file=sys.stderr)
    flip = "; upside down: scans mirrored to read as seen from above" if mount.upside_down else ""
    print(f"rosbag_to_carmen: laser mount x={mount.x:.6f} m y={mount.y:.6f} m theta={mount.theta:.6f} rad "
          f"from {mount.source}{flip}", file=sys.stderr)


# ---------------------------------------------------------------- command line


def parse_offset(text):
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"'{text}': expected X,Y,THETA (metres, metres, radians)")
    return tuple(values)


def parse_args(argv):
    parser = argparse.ArgumentParser(
        prog=pathlib.Path(sys.argv[0]).name or "rosbag_to_carmen.py",  # installed as lshloc-rosbag-to-carmen
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Convert a ROS 2 bag (sqlite3 .db3 or MCAP, MCAP chunks plain, zstd or lz4) or a ROS 1 bag "
                    "(.bag, format 2.0, chunks plain, bz2 or lz4) of "
                    f"{LASER_SCAN} and {ODOMETRY} messages (sensor_msgs/LaserScan and nav_msgs/Odometry in ROS 1) "
                    "into a CARMEN log of ROBOTLASER1 lines for lshloc. "
                    "Each scan gets the odometry interpolated at its stamp and the laser's mount on the robot.",
        epilog="Compression: bags recorded with --compression-mode file (storage files NAME.db3.zstd, "
               "NAME.mcap.zstd, decompressed into a temporary file) or --compression-mode message (each message "
               "zstd-compressed) are read as they are; metadata.yaml says which, and a single file given is "
               "recognised by its zstd magic bytes. Needs the Python module zstandard (python3-zstandard).\n\n"
               "ROS 1 bags: read record by record from the start, not through the index, so a bag whose recording "
               "was cut off converts up to its last whole record (with a warning); tf2_msgs/TFMessage and "
               "tf/tfMessage both give transforms. lz4 chunks need the Python module lz4 (python3-lz4).\n\n"
               "Laser mount: the chain of transforms from the base frame to the scans' frame_id in /tf_static; "
               "where /tf_static lacks a link of it, the link from /tf, when it stays within 1 mm and 0.1 degrees "
               "of its first value over the bag (a laser that moves is refused: give --laser-offset). "
               "The odom -> base transforms on /tf play no part.\n\n"
               "Ranges: ROS's no-return readings (+inf, above range_max) are written as max_range, which lshloc "
               "reads as no return; invalid ones (NaN, -inf, below range_min) as nan, an invalid beam.\n\n"
               "example:\n"
               "  rosbag_to_carmen.py my_bag/ --out run.log.gz\n"
               "  rosbag_to_carmen.py my_ros1.bag --out run.log.gz\n"
               "  lshloc localize --map map.yaml --target run.log.gz")
    parser.add_argument("bag", metavar="BAG",
                        help="a ROS 2 bag directory (the storage files its metadata.yaml lists, else its .db3 / "
                             ".mcap files in name order, each maybe compressed as .zstd) or one such file, or a "
                             "ROS 1 .bag file (format 2.0, known by its first line #ROSBAG V2.0)")
    parser.add_argument("--out", required=True, metavar="LOG",
                        help="the CARMEN log to write; gzip-compressed when it ends in .gz")
    parser.add_argument("--scan-topic", metavar="T",
                        help=f"the {LASER_SCAN} topic (default: the only one in the bag)")
    parser.add_argument("--odom-topic", metavar="T",
                        help=f"the {ODOMETRY} topic (default: the only one; with none, zero odometry is written)")
    parser.add_argument("--base-frame", metavar="F",
                        help="the robot frame the laser mount is measured from in /tf_static or /tf (default: "
                             "the odometry's child_frame_id, else base_link)")
    parser.add_argument("--laser-offset", metavar="X,Y,THETA", type=parse_offset,
                        help="the laser's planar mount on the robot [m, m, rad], overriding /tf_static and /tf; "
                             "the scans "
                             "are taken as upright (write negative values as --laser-offset=-0.1,0,0)")
    parser.add_argument("--stamp", choices=("header", "bag"), default="header",
                        help="time stamps from the messages' headers (default) or the bag's receive times")
    parser.add_argument("--quiet", action="store_true",
                        help="no progress on stderr (the summary and warnings stay)")
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    try:
        convert(args)
    except BagError as e:
        print(f"rosbag_to_carmen: error: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"rosbag_to_carmen: error: {e.filename}: {e.strerror}; expected a readable bag and a writable "
              "output", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
