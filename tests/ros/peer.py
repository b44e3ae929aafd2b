"""An independent ROS 2 peer (rclpy + Fast DDS from PyPI) that exercises fdavar_node.

Run by tests/ros_interop.rs with ROS_DOMAIN_ID set to a domain of the test's own. Each scenario
prints one JSON object on its last stdout line: {"ok": bool, "why": str, ...measurements}. Every wait
is bounded by a deadline.

Scenarios:
  diagnostics  publish sensor_msgs/Imu at 200 Hz, receive /diagnostics (+ typed ~/gyro_x/state when
               fdavar_msgs is importable), see the node in the graph.
  params       list, set (valid, invalid and out of the DAVAR bounds) and get the node's
               parameters through the rcl_interfaces services, as `ros2 param list/set/get` do.
  sim_time     publish rosgraph_msgs/Clock on /clock and see the node's /diagnostics stamps follow it.
  bad_input    publish NaN, backwards, duplicate and zero stamps, a gap, then go silent; the node
               must count each kind and report stale input as ERROR.
  input_loss   a second publisher with its clock 10 s behind, then zero stamps inside the stamped
               stream, then a clean stream: report gyro_x's levels, messages and dropped shares
               of each phase and whether get_parameters still answers.
  temperature  publish Imu at 200 Hz and sensor_msgs/Temperature at 10 Hz for 15 s, the temperature
               ramping 20 -> 40 degC and gyro_x following it at 2e-4 rad/s/K; report the
               temperature coefficient /diagnostics shows for gyro_x and gyro_y.
  play_clock   while `fdavar play --clock` replays a recording, receive /clock as a plain reliable
               subscriber and through rclpy's own time source (a node with use_sim_time), and
               the stamps of fdavar_node's /diagnostics; report them when /clock goes quiet.
  suggestions N  while `fdavar play` replays N samples, wait until the node counted them, then
               report each axis's suggestions, level and message from /diagnostics (and the typed
               ~/gyro_x/state suggestions when fdavar_msgs is importable); the test judges them.
  whole_run MODEL AXIS_MODEL
               while `fdavar play --clock` replays a recording into the node on sim time, check
               /clock arrives; when it has been quiet for 2 s, snapshot every axis's typed
               ~/<axis>/state (model, coefficients, fit_error, failing τ, suggestions, diagnosed
               messages); then set `model` to MODEL and `model.gyro_x` to AXIS_MODEL through
               SetParameters, snapshotting after each refit. The test compares every number with
               `fdavar diagnose/fit --first N` on the same bag.
"""
import json
import math
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy, HistoryPolicy
from sensor_msgs.msg import Imu
from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Clock
from rcl_interfaces.msg import Parameter, ParameterValue, ParameterType
from rcl_interfaces.srv import GetParameters, ListParameters, SetParameters

NODE = "/fdavar"


def finish(ok, why, **extra):
    print(json.dumps({"ok": ok, "why": why, **extra}), flush=True)
    rclpy.try_shutdown()
    sys.exit(0 if ok else 1)


class Peer(Node):
    def __init__(self):
        super().__init__("fdavar_test_peer")
        self.imu_pub = self.create_publisher(Imu, "/imu", qos_profile_sensor_data)
        self.diagnostics = []
        self.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics.append, 10)
        self.stamp_ns = 1_000_000_000
        self.rng_state = 12345

    def noise(self):
        # A small seeded LCG: no numpy needed, same sequence every run.
        self.rng_state = (1103515245 * self.rng_state + 12345) % 2**31
        return self.rng_state / 2**31 - 0.5

    def imu(self, stamp_ns, gx=None):
        m = Imu()
        m.header.frame_id = "imu_link"
        m.header.stamp.sec = stamp_ns // 1_000_000_000
        m.header.stamp.nanosec = stamp_ns % 1_000_000_000
        m.angular_velocity.x = self.noise() * 1e-3 if gx is None else gx
        m.angular_velocity.y = self.noise() * 1e-3
        m.angular_velocity.z = self.noise() * 1e-3
        m.linear_acceleration.x = self.noise() * 1e-2
        m.linear_acceleration.y = self.noise() * 1e-2
        m.linear_acceleration.z = 9.81 + self.noise() * 1e-2
        return m

    def publish_for(self, seconds, rate_hz=200.0):
        period = 1.0 / rate_hz
        step_ns = int(round(period * 1e9))
        end = time.monotonic() + seconds
        next_t = time.monotonic()
        while time.monotonic() < end:
            self.stamp_ns += step_ns
            self.imu_pub.publish(self.imu(self.stamp_ns))
            next_t += period
            rclpy.spin_once(self, timeout_sec=max(0.0, next_t - time.monotonic()))

    def spin_until(self, predicate, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if predicate():
                return True
            rclpy.spin_once(self, timeout_sec=0.05)
        return predicate()

    def wait_for_node(self, seconds=15.0):
        return self.spin_until(
            lambda: any(n == "fdavar" for n, _ in self.get_node_names_and_namespaces()), seconds)

    def wait_for_match(self, seconds=15.0):
        return self.spin_until(lambda: self.imu_pub.get_subscription_count() > 0, seconds)

    def call(self, srv_type, name, request, seconds=10.0):
        client = self.create_client(srv_type, name)
        if not client.wait_for_service(timeout_sec=seconds):
            return None
        future = client.call_async(request)
        self.spin_until(future.done, seconds)
        return future.result() if future.done() else None


def status(array, axis):
    for s in array.status:
        if s.name == f"fdavar: {axis}":
            return s
    return None


def level(s):
    """DiagnosticStatus.level is a `byte`: rclpy gives bytes of length 1."""
    return s.level[0] if isinstance(s.level, (bytes, bytearray)) else int(s.level)


def kv(s, key):
    for v in s.values:
        if v.key == key:
            return v.value
    return None


def subscribe_typed_state(peer):
    """Subscribes gyro_x's typed AxisState when fdavar_msgs (built by colcon from msg/) imports.

    Returns the list the messages are appended to and whether the type was available."""
    typed = []
    try:
        from fdavar_msgs.msg import AxisState
    except ImportError:
        return typed, False
    peer.create_subscription(AxisState, f"{NODE}/gyro_x/state", typed.append, 10)
    return typed, True


def scenario_diagnostics(peer):
    if not peer.wait_for_node():
        finish(False, "fdavar not in the node graph", nodes=peer.get_node_names_and_namespaces())
    if not peer.wait_for_match():
        finish(False, "fdavar_node's imu subscription never matched our publisher")
    typed, have_typed = subscribe_typed_state(peer)
    peer.publish_for(4.0)
    peer.spin_until(lambda: len(peer.diagnostics) >= 2, 5.0)
    if not peer.diagnostics:
        finish(False, "no /diagnostics received")
    last = peer.diagnostics[-1]
    names = sorted(s.name for s in last.status)
    want = sorted(f"fdavar: {a}" for a in
                  ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"])
    if names != want:
        finish(False, "statuses are not one per axis", names=names)
    gx = status(last, "gyro_x")
    samples = int(kv(gx, "samples"))
    rate = float(kv(gx, "rate_hz") or "nan")
    result = dict(samples=samples, rate_hz=rate, level=level(gx), message=gx.message,
                  hardware_id=gx.hardware_id, typed=len(typed), have_typed=have_typed,
                  window_length=kv(gx, "window_length"), f_value=kv(gx, "f_value"))
    if samples < 400:
        finish(False, "too few samples counted (published 800 at 200 Hz)", **result)
    if not (150.0 < rate < 250.0):
        finish(False, "rate_hz is not about 200", **result)
    if gx.hardware_id != "imu_link":
        finish(False, "hardware_id is not the IMU frame", **result)
    # The analysis: W(t) within the default window bounds, F a positive finite ratio.
    w = int(kv(gx, "window_length") or 0)
    f = float(kv(gx, "f_value") or "nan")
    if not (171 <= w <= 501) or not (math.isfinite(f) and f > 0):
        finish(False, "window_length / f_value missing or not sane in /diagnostics", **result)
    if have_typed:
        peer.spin_until(lambda: len(typed) > 0, 5.0)
        result["typed"] = len(typed)
        if not typed:
            finish(False, "no fdavar_msgs/AxisState on ~/gyro_x/state", **result)
        t = typed[-1]
        taus = [p.tau_s for p in t.row]
        result.update(typed_window=t.window_length, typed_f=t.f_value, row_points=len(t.row),
                      coefficients={f"{c.effect}.{c.name}": c.value for c in t.coefficients},
                      fit_error=t.fit_error, axis=t.axis)
        sane = (t.axis == "gyro_x" and 171 <= t.window_length <= 501 and math.isfinite(t.f_value)
                and t.f_value > 0 and len(t.row) >= 3 and taus == sorted(taus)
                and all(p.avar_low <= p.avar <= p.avar_high and p.edf > 0 for p in t.row)
                and abs(t.sample_period_s - 0.005) < 1e-6
                and len(t.coefficients) >= 3 and all(math.isfinite(c.value) and c.value >= 0
                                                     for c in t.coefficients)
                and math.isfinite(t.fit_error))
        if not sane:
            finish(False, "typed AxisState not sane", **result)
    finish(True, "", **result)


def param(name, value):
    p = Parameter()
    p.name = name
    v = ParameterValue()
    if isinstance(value, bool):
        v.type, v.bool_value = ParameterType.PARAMETER_BOOL, value
    elif isinstance(value, float):
        v.type, v.double_value = ParameterType.PARAMETER_DOUBLE, value
    elif isinstance(value, int):
        v.type, v.integer_value = ParameterType.PARAMETER_INTEGER, value
    else:
        v.type, v.string_value = ParameterType.PARAMETER_STRING, value
    p.value = v
    return p


def scenario_params(peer):
    if not peer.wait_for_node():
        finish(False, "fdavar not in the node graph")
    listed = peer.call(ListParameters, f"{NODE}/list_parameters", ListParameters.Request())
    if listed is None:
        finish(False, "list_parameters did not answer")
    names = sorted(listed.result.names)
    for want in ["publish_rate_hz", "queue_size", "model", "qos.reliable", "stale_timeout_s",
                 "diagnosis_period_s"]:
        if want not in names:
            finish(False, f"parameter {want} not listed", names=names)

    def get(name):
        r = peer.call(GetParameters, f"{NODE}/get_parameters", GetParameters.Request(names=[name]))
        return None if r is None or not r.values else r.values[0]

    before = get("publish_rate_hz").double_value
    req = SetParameters.Request(parameters=[param("publish_rate_hz", -1.0),
                                            param("queue_size", 5),
                                            param("publish_rate_hz", 4.0)])
    r = peer.call(SetParameters, f"{NODE}/set_parameters", req)
    if r is None:
        finish(False, "set_parameters did not answer")
    results = [(x.successful, x.reason) for x in r.results]
    after = get("publish_rate_hz").double_value
    ok = (len(results) == 3 and not results[0][0] and "(0, 100]" in results[0][1]
          and not results[1][0] and "startup" in results[1][1] and results[2][0]
          and after == 4.0)
    if not ok:
        finish(False, "set_parameters results are not as expected", names=names,
               results=results, before=before, after=after)
    # DAVAR settings: checked together (window.min <= window.max), live-runnable only.
    req = SetParameters.Request(parameters=[param("window.min", 900),
                                            param("sigma_ref.mode", "record"),
                                            param("window.min", 201)])
    r = peer.call(SetParameters, f"{NODE}/set_parameters", req)
    davar = [(x.successful, x.reason) for x in r.results] if r else []
    wmin = get("window.min").integer_value
    mode = get("sigma_ref.mode").string_value
    ok = (len(davar) == 3 and not davar[0][0] and "window.max" in davar[0][1]
          and not davar[1][0] and "record" in davar[1][1] and davar[2][0]
          and wmin == 201 and mode == "running")
    if not ok:
        finish(False, "DAVAR parameter changes not as expected", names=names,
               results=results, davar=davar, window_min=wmin, sigma_ref_mode=mode, after=after)
    # Issue 13: values that panicked the spin thread (window.max 2^63-1: capacity overflow, later
    # calls timed out) or froze the analysis while answered "successful" (tau0 1e-300) are refused
    # with the bound; the node goes on answering (below) and publishing (the window change below).
    # The others that aborted (8 GB allocations) or ran out of memory after seconds, likewise.
    req = SetParameters.Request(parameters=[param("window.max", 9223372036854775807),
                                            param("tau0", 1e-300),
                                            param("window.max", 1000000000),
                                            param("window.max", 10000000),
                                            param("window.length", 1000000000),
                                            param("window.length", 60001)])
    r = peer.call(SetParameters, f"{NODE}/set_parameters", req)
    bounds = [(x.successful, x.reason) for x in r.results] if r else []
    wmax = get("window.max")
    want = ["'window.max'", "'tau0'", "'window.max'", "'window.max'", "'window.length'",
            "'window.length'"]
    ok = (len(bounds) == len(want)
          and all(not done and name in why for (done, why), name in zip(bounds, want))
          and all("[3, 50001]" in why for _, why in bounds[:1] + bounds[2:])
          and "[1e-5, 86400]" in bounds[1][1]
          and wmax is not None and wmax.integer_value == 501)
    if not ok:
        finish(False, "out-of-bounds DAVAR values not refused as expected", bounds=bounds)
    # A live window change reconfigures the running analysis: a fixed window of 301 samples.
    if not peer.wait_for_match():
        finish(False, "imu subscription never matched")
    peer.publish_for(2.0)
    r = peer.call(SetParameters, f"{NODE}/set_parameters", SetParameters.Request(
        parameters=[param("window.length", 301), param("window.policy", "fixed")]))
    live = [(x.successful, x.reason) for x in r.results] if r else []
    peer.publish_for(3.0)
    peer.diagnostics.clear()
    peer.spin_until(lambda: len(peer.diagnostics) >= 1, 3.0)
    w = kv(status(peer.diagnostics[-1], "gyro_x"), "window_length") if peer.diagnostics else None
    ok = live == [(True, ""), (True, "")] and w == "301"
    finish(ok, "" if ok else "live window change did not reach the analysis", davar=davar,
           results=results, live=live, window_length=w, bounds=bounds)


def scenario_sim_time(peer):
    clock_pub = peer.create_publisher(Clock, "/clock", 10)
    if not peer.wait_for_node():
        finish(False, "fdavar not in the node graph")
    if not peer.spin_until(lambda: clock_pub.get_subscription_count() > 0, 15.0):
        finish(False, "fdavar_node did not subscribe /clock as rosgraph_msgs/msg/Clock")
    sim_s = 1000
    end = time.monotonic() + 4.0
    while time.monotonic() < end:
        sim_s += 1
        c = Clock()
        c.clock.sec = sim_s
        clock_pub.publish(c)
        rclpy.spin_once(peer, timeout_sec=0.1)
    stamps = [d.header.stamp.sec + d.header.stamp.nanosec * 1e-9 for d in peer.diagnostics]
    ok = bool(stamps) and all(1000 < s <= sim_s for s in stamps[-3:])
    finish(ok, "" if ok else "the node's stamps do not follow /clock", stamps=stamps[-5:],
           clock=sim_s)


def scenario_bad_input(peer):
    if not peer.wait_for_node() or not peer.wait_for_match():
        finish(False, "fdavar_node not up / not matched")
    peer.publish_for(1.5)
    t = peer.stamp_ns
    step = 5_000_000
    bad = [peer.imu(t + step, gx=math.nan), peer.imu(t + step, gx=math.inf),
           peer.imu(t), peer.imu(t - 10 * step), peer.imu(0)]
    for m in bad:
        peer.imu_pub.publish(m)
        rclpy.spin_once(peer, timeout_sec=0.01)
    peer.stamp_ns = t + 40 * step  # a gap
    peer.publish_for(1.5)
    peer.diagnostics.clear()
    peer.spin_until(lambda: len(peer.diagnostics) >= 1, 3.0)
    if not peer.diagnostics:
        finish(False, "no /diagnostics")
    gx = status(peer.diagnostics[-1], "gyro_x")
    counts = {k: int(kv(gx, k)) for k in
              ["non_finite", "duplicates", "backwards", "zero_stamps", "gaps"]}
    ok = (counts["non_finite"] >= 2 and counts["duplicates"] >= 1 and counts["backwards"] >= 1
          and counts["zero_stamps"] >= 1 and counts["gaps"] >= 1)
    if not ok:
        finish(False, "bad inputs not counted", counts=counts)
    # Silence: the node must report stale input (ERROR) within stale_timeout_s + a publish period.
    peer.diagnostics.clear()
    stale = peer.spin_until(lambda: any(
        level(status(d, "gyro_x")) == 2 and "stale" in status(d, "gyro_x").message
        for d in peer.diagnostics), 6.0)
    finish(stale, "" if stale else "silence not reported as stale ERROR", counts=counts)


def scenario_input_loss(peer):
    """Issue 13: a second publisher whose clock is 10 s behind (every one of its messages is
    backwards), then zero stamps inside the stamped stream (three per good message). Reports the
    gyro_x levels, messages and dropped shares /diagnostics gave in each phase (the first two
    publications of a phase, which straddle its start, left out), whether get_parameters still
    answers, and the same for a clean phase after; the test judges them."""
    second = peer.create_publisher(Imu, "/imu", qos_profile_sensor_data)
    if not peer.wait_for_node() or not peer.wait_for_match():
        finish(False, "fdavar_node not up / not matched")
    peer.spin_until(lambda: second.get_subscription_count() > 0, 15.0)
    peer.publish_for(1.5)

    def phase(seconds, extra):
        peer.diagnostics.clear()
        end = time.monotonic() + seconds
        next_t = time.monotonic()
        while time.monotonic() < end:
            peer.stamp_ns += 5_000_000
            peer.imu_pub.publish(peer.imu(peer.stamp_ns))
            for stamp in extra(peer.stamp_ns):
                second.publish(peer.imu(stamp))
            next_t += 0.005
            rclpy.spin_once(peer, timeout_sec=max(0.0, next_t - time.monotonic()))
        seen = [status(d, "gyro_x") for d in peer.diagnostics[2:]]
        return {"levels": [level(s) for s in seen], "messages": [s.message for s in seen],
                "shares": [kv(s, "dropped_share") for s in seen],
                "samples": int(kv(seen[-1], "samples")) if seen else None}

    offset = phase(3.0, lambda t: [t - 10_000_000_000])
    zero = phase(3.0, lambda t: [0, 0, 0])
    r = peer.call(GetParameters, f"{NODE}/get_parameters",
                  GetParameters.Request(names=["publish_rate_hz"]))
    answered = r.values[0].double_value if r and r.values else None
    clean = phase(3.0, lambda t: [])
    finish(True, "", offset=offset, zero=zero, clean=clean, answered=answered)


def scenario_flood(peer):
    """Publish as fast as rclpy can (≫ 10× a 200 Hz IMU) for 5 s; report what was sent and counted."""
    if not peer.wait_for_node() or not peer.wait_for_match():
        finish(False, "fdavar_node not up / not matched")
    print("flood-start", flush=True)  # the Rust test samples the node's RSS here
    sent = 0
    end = time.monotonic() + 5.0
    while time.monotonic() < end:
        for _ in range(100):
            peer.stamp_ns += 500_000
            peer.imu_pub.publish(peer.imu(peer.stamp_ns))
            sent += 1
        rclpy.spin_once(peer, timeout_sec=0.0)
    print("flood-end", flush=True)
    peer.diagnostics.clear()
    peer.spin_until(lambda: len(peer.diagnostics) >= 2, 5.0)
    if not peer.diagnostics:
        finish(False, "no /diagnostics after the flood")
    gx = status(peer.diagnostics[-1], "gyro_x")
    samples, drops = int(kv(gx, "samples")), int(kv(gx, "drops"))
    ok = samples > 0 and samples + drops <= sent
    finish(ok, "" if ok else "counts do not add up", sent=sent, samples=samples, drops=drops,
           rate_s=sent / 5.0)


def scenario_expect_samples(peer):
    """Wait (bounded) until the node has counted exactly N samples (N = argv[2]), e.g. while
    `fdavar play` replays a recording of N messages into it."""
    want = int(sys.argv[2])
    if not peer.wait_for_node():
        finish(False, "fdavar not in the node graph")
    seen = []

    def done():
        if peer.diagnostics:
            gx = status(peer.diagnostics[-1], "gyro_x")
            seen.append(int(kv(gx, "samples")))
            peer.diagnostics.clear()
        return bool(seen) and seen[-1] >= want

    peer.spin_until(done, 60.0)
    peer.diagnostics.clear()
    peer.spin_until(lambda: len(peer.diagnostics) >= 1, 3.0)
    last = status(peer.diagnostics[-1], "gyro_x") if peer.diagnostics else None
    counts = {k: int(kv(last, k)) for k in ["samples", "drops", "gaps", "duplicates", "backwards"]} \
        if last else {}
    ok = counts.get("samples") == want and counts.get("gaps") == 0 and counts.get("drops") == 0
    finish(ok, "" if ok else f"the node did not count exactly {want} samples", counts=counts,
           rate_hz=kv(last, "rate_hz") if last else None)


def scenario_model(peer):
    """A hidden sinusoid on gyro_x: with model N,B,K the fit fails; after `ros2 param set model
    N,B,K,sinusoid` the published fit_error must fall at least 3x. An invalid model is refused."""
    import random
    rng = random.Random(52)
    if not peer.wait_for_node() or not peer.wait_for_match():
        finish(False, "fdavar_node not up / not matched")

    def run(seconds):
        fit = []
        end = time.monotonic() + seconds
        next_t = time.monotonic()
        while time.monotonic() < end:
            peer.stamp_ns += 5_000_000
            t = peer.stamp_ns * 1e-9
            gx = 1e-3 * rng.gauss(0, 1) + 3e-3 * math.sin(2 * math.pi * 2.0 * t)
            peer.imu_pub.publish(peer.imu(peer.stamp_ns, gx=gx))
            next_t += 0.005
            rclpy.spin_once(peer, timeout_sec=max(0.0, next_t - time.monotonic()))
            while peer.diagnostics:
                v = kv(status(peer.diagnostics.pop(0), "gyro_x"), "fit_error")
                if v is not None and math.isfinite(float(v)):
                    fit.append(float(v))
        return fit

    before = run(6.0)
    r = peer.call(SetParameters, f"{NODE}/set_parameters", SetParameters.Request(
        parameters=[param("model", "N,warp_drive"), param("model", "N,B,K,sinusoid")]))
    results = [(x.successful, x.reason) for x in r.results] if r else []
    after = run(8.0)
    if len(before) < 2 or len(after) < 1:
        finish(False, "too few fit_error values", before=before, after=after, results=results)
    b = sorted(before[-3:])[len(before[-3:]) // 2]
    a = sorted(after[-3:])[len(after[-3:]) // 2]
    ok = (len(results) == 2 and not results[0][0] and "warp_drive" in results[0][1]
          and results[1][0] and b >= 3 * a)
    finish(ok, "" if ok else "fit_error did not fall 3x / refusal wrong", before=before,
           after=after, results=results, ratio=b / a if a > 0 else None)


def scenario_temperature(peer):
    import random
    from sensor_msgs.msg import Temperature
    rng = random.Random(7)
    temp_pub = peer.create_publisher(Temperature, "/temperature", qos_profile_sensor_data)
    if not peer.wait_for_node() or not peer.wait_for_match():
        finish(False, "fdavar_node not up / not matched")
    if not peer.spin_until(lambda: temp_pub.get_subscription_count() > 0, 15.0):
        finish(False, "fdavar_node did not subscribe /temperature")
    seconds = 15.0
    start = time.monotonic()
    next_t = start
    k = 0
    while time.monotonic() < start + seconds:
        celsius = 20.0 + 20.0 * (time.monotonic() - start) / seconds
        peer.stamp_ns += 5_000_000
        gx = 1e-3 * rng.gauss(0, 1) + 2e-4 * (celsius - 30.0)
        peer.imu_pub.publish(peer.imu(peer.stamp_ns, gx=gx))
        if k % 20 == 0:
            t = Temperature()
            t.header.frame_id = "imu_link"
            t.header.stamp.sec = peer.stamp_ns // 1_000_000_000
            t.header.stamp.nanosec = peer.stamp_ns % 1_000_000_000
            t.temperature = celsius
            temp_pub.publish(t)
        k += 1
        next_t += 0.005
        rclpy.spin_once(peer, timeout_sec=max(0.0, next_t - time.monotonic()))
    peer.diagnostics.clear()
    peer.spin_until(lambda: len(peer.diagnostics) >= 1, 3.0)
    if not peer.diagnostics:
        finish(False, "no /diagnostics")
    key = "temperature.coefficient_per_k [rad/s/K]"
    last = peer.diagnostics[-1]
    found = {a: kv(status(last, a), key) for a in ["gyro_x", "gyro_y"]}
    finish(True, "", coefficient=found, sent=k)


def scenario_play_clock(peer):
    from rclpy.parameter import Parameter as RclpyParameter
    # rclpy's time source subscribes /clock best effort, depth 1 (what a node on sim time does).
    sim = Node("fdavar_sim_time_peer",
               parameter_overrides=[RclpyParameter("use_sim_time", RclpyParameter.Type.BOOL, True)])
    clock = []  # ns, as a plain subscriber (reliable, depth 100: `ros2 topic echo /clock`) got them
    peer.create_subscription(Clock, "/clock",
                             lambda m: clock.append(m.clock.sec * 10**9 + m.clock.nanosec), 100)
    diag = []  # (stamp ns, gyro_x samples) of the node's /diagnostics
    if not peer.wait_for_node():
        finish(False, "fdavar not in the node graph")

    def spin(seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(peer, timeout_sec=0.01)
            rclpy.spin_once(sim, timeout_sec=0.0)
            while peer.diagnostics:
                d = peer.diagnostics.pop(0)
                gx = status(d, "gyro_x")
                diag.append((d.header.stamp.sec * 10**9 + d.header.stamp.nanosec,
                             int(kv(gx, "samples") or 0) if gx else 0))

    deadline = time.monotonic() + 90.0
    while not clock and time.monotonic() < deadline:
        spin(0.1)
    if not clock:
        finish(False, "no /clock received")
    # Playing: until /clock has been quiet for 2 s (the player ended), then one more second of
    # /diagnostics.
    while time.monotonic() < deadline:
        n = len(clock)
        spin(2.0)
        if len(clock) == n:
            break
    spin(1.0)
    now = sim.get_clock().now().nanoseconds
    finish(True, "", clock_count=len(clock), clock_first=clock[0], clock_last=clock[-1],
           clock_increasing=all(b > a for a, b in zip(clock, clock[1:])), clock=clock,
           sim_now=now, diagnostics=diag)


AXES = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]


def scenario_suggestions(peer):
    want = int(sys.argv[2])
    if not peer.wait_for_node():
        finish(False, "fdavar not in the node graph")
    typed, have_typed = subscribe_typed_state(peer)

    def counted():
        return bool(peer.diagnostics) and int(
            kv(status(peer.diagnostics[-1], "gyro_x"), "samples")) >= want

    if not peer.spin_until(counted, 90.0):
        finish(False, f"the node did not count {want} samples")
    # A whole diagnosis round after the last sample (the test sets diagnosis_period_s 1 s and
    # publishes at 10 Hz: six axes in 0.6 s).
    peer.spin_until(lambda: False, 3.0)
    last = peer.diagnostics[-1]
    result = {
        "suggestions": {a: kv(status(last, a), "suggestions") for a in AXES},
        "levels": {a: level(status(last, a)) for a in AXES},
        "messages": {a: status(last, a).message for a in AXES},
        "have_typed": have_typed,
    }
    if have_typed:
        if not typed:
            finish(False, "no fdavar_msgs/AxisState on ~/gyro_x/state", **result)
        result["typed"] = [
            {"effect": x.effect, "fit_error_after": x.fit_error_after,
             "explanation": x.explanation,
             "params": {p.name: [p.value, p.unit] for p in x.params}}
            for x in typed[-1].suggestions]
    finish(True, "", **result)


def finite(x):
    """JSON has no NaN: a value without one (e.g. a σ the fit could not give) becomes null."""
    return x if math.isfinite(x) else None


def whole_run_fields(state):
    """The whole-run fields of a typed AxisState, every float exact (json writes repr)."""
    def coefficients(cs):
        return [{"effect": c.effect, "name": c.name, "value": finite(c.value),
                 "sigma": finite(c.sigma), "unit": c.unit} for c in cs]
    return {
        "model": list(state.model),
        "coefficients": coefficients(state.coefficients),
        "fit_error": finite(state.fit_error),
        "span_fit_error": finite(state.span_fit_error),
        "rate_excess_kurtosis": finite(state.rate_excess_kurtosis),
        "failing_tau": [[t.low_s, t.high_s] for t in state.failing_tau],
        "failing_spans": [[t.start_s, t.end_s] for t in state.failing_spans],
        "suggestions": [{"effect": x.effect, "fit_error_after": finite(x.fit_error_after),
                         "span_fit_error_after": finite(x.span_fit_error_after),
                         "params": coefficients(x.params), "given": list(x.given)}
                        for x in state.suggestions],
        "diagnosed_messages": state.diagnosed_messages,
        "samples": state.samples,
        "drops": state.drops,
        "gaps": state.gaps,
    }


def scenario_whole_run(peer):
    from fdavar_msgs.msg import AxisState
    model, axis_model = sys.argv[2], sys.argv[3]
    clock = []
    peer.create_subscription(Clock, "/clock", lambda m: clock.append(m.clock.sec), 100)
    latest = {}
    for a in AXES:
        peer.create_subscription(AxisState, f"{NODE}/{a}/state",
                                 lambda m, a=a: latest.__setitem__(a, m), 10)
    if not peer.wait_for_node():
        finish(False, "fdavar not in the node graph")
    if not peer.spin_until(lambda: bool(clock), 90.0):
        finish(False, "no /clock received")
    # Playing until /clock has been quiet for 2 s; then the node's last round on the frozen clock.
    deadline = time.monotonic() + 240.0
    while time.monotonic() < deadline:
        n = len(clock)
        peer.spin_until(lambda: False, 2.0)
        if len(clock) == n:
            break
    peer.spin_until(lambda: False, 3.0)
    if len(latest) < len(AXES):
        finish(False, f"typed state only on {sorted(latest)}")
    snapshots = {"played": {a: whole_run_fields(latest[a]) for a in AXES}}

    def refit(name, value, axes, label):
        r = peer.call(SetParameters, f"{NODE}/set_parameters",
                      SetParameters.Request(parameters=[param(name, value)]))
        if not r or not r.results[0].successful:
            finish(False, f"{name}:={value} refused", result=str(r), **snapshots)
        want = value.split(",")
        # The change starts a round at once, one axis per publication (10 Hz): wait for each
        # axis to show the new model, then one more publication.
        if not peer.spin_until(lambda: all(list(latest[a].model) == want for a in axes), 30.0):
            finish(False, f"{name}:={value} never published",
                   models={a: list(latest[a].model) for a in axes}, **snapshots)
        peer.spin_until(lambda: False, 0.5)
        snapshots[label] = {a: whole_run_fields(latest[a]) for a in axes}

    refit("model", model, AXES, "model")
    refit("model.gyro_x", axis_model, ["gyro_x"], "axis_model")
    finish(True, "", clock_count=len(clock), **snapshots)


def main():
    rclpy.init()
    peer = Peer()
    scenario = sys.argv[1]
    {"diagnostics": scenario_diagnostics, "params": scenario_params,
     "sim_time": scenario_sim_time, "bad_input": scenario_bad_input, "flood": scenario_flood,
     "expect_samples": scenario_expect_samples, "model": scenario_model,
     "suggestions": scenario_suggestions, "temperature": scenario_temperature,
     "play_clock": scenario_play_clock, "whole_run": scenario_whole_run,
     "input_loss": scenario_input_loss}[scenario](peer)


if __name__ == "__main__":
    main()
