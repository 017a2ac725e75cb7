#!/usr/bin/python3
"""lshloc_ros_node against a real ROS master on a free loopback port and `rosbag play --clock` of bags
written here with the rosbag API from a simulated building (known truth):
- /initialpose in frame "map" within 0.5 m and 5 degrees of the true robot pose, ~status every scan;
- a bag with NaN ranges and a scan whose frame tf cannot resolve, then a second bag of the run 500 s earlier with
  its sweeps reversed (the clock runs back): the node stays up, starts over and announces the pose again;
- odometry from a nav_msgs/Odometry topic instead of tf: the same answer;
- ROS occupancy grids as the map (ray-cast with the robot's laser at its first scan): the same answer;
- a map that cannot be loaded: the node stays up and each status says why.
Usage: ros_node_test.py NODE LSHLOC   (Debian's /usr/bin/python3: rospy and rosbag)"""
import bisect, gzip, json, math, os, shutil, signal, socket, subprocess, sys, tempfile, time

NODE, LSHLOC = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
work = tempfile.mkdtemp(prefix="lshloc-ros-")
port = None
with socket.socket() as s:
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_HOSTNAME="127.0.0.1", ROS_IP="127.0.0.1",
           ROS_HOME=os.path.join(work, "roshome"), ROS_LOG_DIR=os.path.join(work, "roslog"))
os.environ.update(env)
import rosbag, rospy  # noqa: E402 (after the environment names the master)
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from sensor_msgs.msg import LaserScan  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

MOUNT = 0.12  # [m] the laser ahead of base_link


def fail(text):
    print("FAIL: " + text)
    sys.exit(1)


def read_flaser(path):
    """(stamp, ranges, odometry x, y, theta) of each FLASER line."""
    out = []
    for line in gzip.open(path, "rt"):
        f = line.split()
        if f and f[0] == "FLASER":
            n = int(f[1])
            rest = f[2 + n:]
            out.append((float(rest[6]), [float(v) for v in f[2:2 + n]], float(rest[3]), float(rest[4]), float(rest[5])))
    return out


def transform(stamp, parent, child, x, y, theta):
    t = TransformStamped()
    t.header.stamp, t.header.frame_id, t.child_frame_id = stamp, parent, child
    t.transform.translation.x, t.transform.translation.y = x, y
    t.transform.rotation.z, t.transform.rotation.w = math.sin(theta / 2), math.cos(theta / 2)
    return t


def write_bag(path, scans, faults=False, shift=0.0):
    """/scan (frame laser), /tf odom -> base_link from the log's odometry, /tf_static base_link -> laser.
    faults: every 7th range NaN and scan 30 in an unknown frame; shift: the stamps moved, the sweeps reversed."""
    bag = rosbag.Bag(path, "w")
    t0 = rospy.Time.from_sec(scans[0][0] + shift - 1.0)
    bag.write("/tf_static", TFMessage([transform(t0, "base_link", "laser", MOUNT, 0.0, 0.0)]), t0)
    for i, (t, ranges, ox, oy, oth) in enumerate(scans):
        st = rospy.Time.from_sec(t + shift)
        # The log's odometry is the laser's: base_link sits MOUNT behind it.
        bx, by = ox - MOUNT * math.cos(oth), oy - MOUNT * math.sin(oth)
        bag.write("/tf", TFMessage([transform(st, "odom", "base_link", bx, by, oth)]), st)
        odom = Odometry()
        odom.header.stamp, odom.header.frame_id, odom.child_frame_id = st, "odom", "base_link"
        odom.pose.pose.position.x, odom.pose.pose.position.y = bx, by
        odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = math.sin(oth / 2), math.cos(oth / 2)
        bag.write("/odom", odom, st)
        s = LaserScan()
        s.header.stamp = st
        s.header.frame_id = "no_such_frame" if faults and i == 30 else "laser"
        n = len(ranges)
        s.angle_min, s.angle_max, s.angle_increment = -math.pi / 2, math.pi / 2, math.pi / (n - 1)
        s.range_min, s.range_max = 0.0, 49.9
        r = [float("nan") if faults and k % 7 == 0 else v for k, v in enumerate(ranges)]
        if shift < 0:  # the same sweep the other way round
            s.angle_min, s.angle_max, s.angle_increment, r = math.pi / 2, -math.pi / 2, -s.angle_increment, r[::-1]
        s.ranges = r
        bag.write("/scan", s, st)
    bag.close()


procs = []


def start(cmd, log):
    p = subprocess.Popen(cmd, env=env, stdout=open(log, "w"), stderr=subprocess.STDOUT, start_new_session=True)
    procs.append(p)
    return p


def stop_all():
    for p in reversed(procs):
        try:
            os.killpg(p.pid, signal.SIGINT)
        except ProcessLookupError:
            pass
    for p in reversed(procs):
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    procs.clear()


def run_node(maps, bags, name, *params):
    """Starts the node on `maps`, plays `bags` one after the other with --clock, returns what it published."""
    seen = dict(initialposes=[], status=[])
    node = start([NODE, f"_maps:={maps}", "__name:=lshloc", *params], os.path.join(work, name + ".node.log"))
    subs = [rospy.Subscriber("/initialpose", PoseWithCovarianceStamped, lambda m: seen["initialposes"].append(m),
                             queue_size=100),
            rospy.Subscriber("/lshloc/status", String, lambda m: seen["status"].append(json.loads(m.data)),
                             queue_size=2000)]
    for _ in range(300):  # until the node has loaded its map and subscribed to /scan (bounded: 30 s)
        _, _, (_, subscribers, _) = rospy.get_master().getSystemState()
        if any(topic == "/scan" and "/lshloc" in nodes for topic, nodes in subscribers):
            break
        if node.poll() is not None:
            fail(f"the node exited ({node.returncode}) before subscribing; see {name}.node.log")
        time.sleep(0.1)
    else:
        fail("the node did not subscribe to /scan within 30 s")
    for bag in bags:
        subprocess.run(["rosbag", "play", "--clock", "-q", "-r", "4", bag], env=env, timeout=600,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    time.sleep(2)
    seen["alive"] = node.poll() is None
    for s in subs:
        s.unregister()
    os.killpg(node.pid, signal.SIGINT)
    node.wait(timeout=10)
    procs.remove(node)
    return seen


try:
    sim = os.path.join(work, "sim")
    subprocess.run([LSHLOC, "simulate", "--out", sim, "--buildings", "2", "--seed", "3", "--scans", "600"],
                   check=True, capture_output=True)
    a, b = os.path.join(sim, "sim-3-000"), os.path.join(sim, "sim-3-001")
    mapfile = os.path.join(work, "two.map")
    subprocess.run([LSHLOC, "map", "build", "--out", mapfile, a + "/sim-3-000-corrected.log.gz",
                    b + "/sim-3-001-corrected.log.gz"], check=True, capture_output=True)
    scans = read_flaser(b + "/sim-3-001.log.gz")[300:450]
    truth = sorted(tuple(map(float, l.split()[:4])) for l in open(b + "/sim-3-001.gfs-poses-at-raw-stamps.txt")
                   if l.strip() and not l.startswith("#"))
    stamps = [t[0] for t in truth]
    write_bag(os.path.join(work, "right.bag"), scans)
    write_bag(os.path.join(work, "faults.bag"), scans, faults=True)
    write_bag(os.path.join(work, "earlier.bag"), scans, faults=True, shift=-500.0)

    start(["rosmaster", "--core", "-p", str(port)], os.path.join(work, "master.log"))
    for _ in range(100):  # until the master answers (bounded: 10 s)
        if subprocess.run(["rosparam", "set", "/use_sim_time", "true"], env=env, capture_output=True).returncode == 0:
            break
        time.sleep(0.1)
    else:
        fail("rosmaster did not start on port %d" % port)
    rospy.init_node("ros_node_test", anonymous=True, disable_signals=True)

    def off(msg, shift=0.0):
        """Position [m] and heading [deg] error of a published robot pose against the truth (laser poses)."""
        t = msg.header.stamp.to_sec() - shift
        i = min(bisect.bisect_left(stamps, t), len(stamps) - 1)
        _, x, y, th = truth[i]
        q = msg.pose.pose.orientation
        yaw = math.atan2(2 * q.w * q.z, 1 - 2 * q.z * q.z)
        lx, ly = msg.pose.pose.position.x + MOUNT * math.cos(yaw), msg.pose.pose.position.y + MOUNT * math.sin(yaw)
        return math.hypot(lx - x, ly - y), abs(math.degrees(math.remainder(yaw - th, 2 * math.pi)))

    right = run_node(mapfile, [os.path.join(work, "right.bag")], "right")
    ip = right["initialposes"]
    if not right["alive"]:
        fail("the node died on a plain bag")
    if not ip:
        fail(f"no /initialpose over {len(scans)} scans; last status {right['status'][-1:]}")
    plain_errors = [off(m) for m in ip]
    if not all(e[0] <= 0.5 and e[1] <= 5 for e in plain_errors):
        fail(f"/initialpose off the truth: {plain_errors}")
    if not all(m.header.frame_id == "map" and m.pose.covariance[0] > 0 for m in ip):
        fail("/initialpose not in frame map with a positive covariance")
    if len(right["status"]) < len(scans) * 0.8:
        fail(f"{len(right['status'])} status messages for {len(scans)} scans")
    last = right["status"][-1]
    if not (last.get("confident") and last.get("submap") == "sim-3-001-corrected.log.gz"):
        fail(f"last status: {last}")

    # Odometry from nav_msgs/Odometry (~odom_topic) instead of tf: the same answer.
    topic = run_node(mapfile, [os.path.join(work, "right.bag")], "topic", "_odom_topic:=odom")
    topic_errors = [off(m) for m in topic["initialposes"]]
    if not topic["alive"] or not topic_errors or not all(e[0] <= 0.5 and e[1] <= 5 for e in topic_errors):
        fail(f"odometry from ~odom_topic: /initialpose off by {topic_errors}; last status {topic['status'][-1:]}")

    faults = run_node(mapfile, [os.path.join(work, "faults.bag"), os.path.join(work, "earlier.bag")], "faults")
    first = [m for m in faults["initialposes"] if m.header.stamp.to_sec() > scans[0][0] - 100]
    second = [m for m in faults["initialposes"] if m.header.stamp.to_sec() < scans[0][0] - 100]
    if not faults["alive"]:
        fail("the node died on NaN ranges, an unknown frame or time running back")
    if not first or not second:
        fail(f"/initialpose {len(first)} times in the first pass, {len(second)} after time ran back (each >= 1)")
    errors = [off(m) for m in first] + [off(m, -500.0) for m in second]
    if not all(e[0] <= 0.5 and e[1] <= 5 for e in errors):
        fail(f"/initialpose off the truth with faults (reversed sweeps after the jump): {errors}")
    if not any("no_such_frame" in s.get("error", "") for s in faults["status"]):
        fail("the scan in an unknown frame was not said in ~status")
    if not any(s.get("restarted") for s in faults["status"]):
        fail("time running back was not said in ~status")

    # ROS occupancy grids as the map: built at the first scan, ray-cast with the robot's own laser.
    for stem, log in (("ga", a + "/sim-3-000-corrected.log.gz"), ("gb", b + "/sim-3-001-corrected.log.gz")):
        subprocess.run([LSHLOC, "map", "to-grid", log, "--out", os.path.join(work, stem)], check=True,
                       capture_output=True)
    grid = run_node(os.path.join(work, "ga.yaml") + ";" + os.path.join(work, "gb.yaml"),
                    [os.path.join(work, "right.bag")], "grid")
    grid_errors = [off(m) for m in grid["initialposes"]]
    if not grid["alive"] or not grid_errors or not all(e[0] <= 0.5 and e[1] <= 5 for e in grid_errors):
        fail(f"ROS grids as the map: /initialpose off by {grid_errors}; last status {grid['status'][-1:]}")
    if grid["status"][-1].get("submap") != "gb":
        fail(f"ROS grids: the last status names {grid['status'][-1].get('submap')}, not gb")

    broken = run_node(os.path.join(work, "missing.map"), [os.path.join(work, "right.bag")], "broken")
    if not broken["alive"]:
        fail("the node died on a map it cannot load")
    if not broken["status"] or not all("missing.map" in s.get("error", "") for s in broken["status"]):
        fail(f"a map that failed to load is not said in ~status: {broken['status'][:1]}")
    print(f"ros_node: {len(ip)} /initialpose on the plain bag (worst {max(e[0] for e in plain_errors):.3f} m), "
          f"{len(first)} + {len(second)} with faults and time running back; {len(grid_errors)} on ROS grids "
          f"(worst {max(e[0] for e in grid_errors):.3f} m); a missing map said, node alive")
finally:
    stop_all()
    shutil.rmtree(work, ignore_errors=True)
