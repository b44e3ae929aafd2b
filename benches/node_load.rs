//! Benchmark of `fdavar_node` under a 2 kHz IMU: its CPU share and its receive-to-update latency.
//!
//! ```text
//! cargo bench --bench node_load -- [RATE_HZ] [SECONDS] [DIAGNOSIS_PERIOD_S] [SINUSOID] [CPU_SHARE] [BATCH_MS] [PEERS]
//! ```
//! (defaults 2000 Hz, 20 s, the node's default diagnosis period, 10 s (0 turns it off), no
//! sinusoid, the node's default `diagnosis_cpu_share`, 0.005, and its default
//! `receive_batch_ms`, 0.8 (0: woken by DDS for every message); SINUSOID = a peak amplitude in
//! rad/s adds a 2 Hz sinusoid to gyro_x, so that its model fails and each diagnosis of that axis
//! refits every candidate effect: the costly case; a period of 1 s with CPU_SHARE 1 runs the rounds
//! back to back, so that the latency window always holds diagnoses).
//! Starts the release `fdavar_node` on ROS_DOMAIN_ID 90, publishes `sensor_msgs/Imu` at RATE_HZ from
//! this process (ros2-client, best effort), and reads
//! - CPU share: the node's user+system time (/proc/PID/stat) over the publishing wall time;
//! - latency: the node's own `latency_p50_ms` / `latency_p99_ms` from `/diagnostics` (time from
//!   RustDDS's reception stamp of a message to the end of its analysis update, over the last 8192
//!   samples);
//! - samples counted and drops (a full analysis queue);
//! - the cost of the latest whole-run diagnosis of gyro_x (`diagnosis_ms`), which runs on a
//!   thread of its own, one axis per publication.
//!
//! - the same CPU share per thread (/proc/PID/task/*/stat; threads that used none are left out),
//!   with each thread's wake-ups per second (its `voluntary_ctxt_switches`);
//! - after the node and the peers are gone, this host's price of a wake-up, measured by threads
//!   that do nothing else: one sleeping a batch's length at a time (the node's receive thread
//!   between batches), and one woken by a UDP datagram at RATE_HZ, on the sender's CPU and on
//!   another (what RustDDS's thread is, per message); beside them,
//!   the node's busy threads' CPU per wake-up. On this project's virtual machine a wake-up of an
//!   idle CPU costs 15–37 µs, and the node's share at 2 kHz is nearly all wake-ups
//!   (docs/ros.md, "Threads").
//!
//! PEERS (default `bare`; `bare,rclpy`, `rclpy`, or `none` for the node alone) are subscribers measured in the same
//! minutes as the node, on the same messages, so that the node's share can be read against what
//! the host charges for a 2 kHz subscription at all (the host's speed moved the node's share by up
//! to 2.5× between days, docs/performance.md):
//! - `bare`: this bench re-run as a ros2-client subscriber that takes each message as DDS wakes it
//!   and does nothing else: the floor of the DDS stack the node is built on;
//! - `rclpy`: a plain rclpy subscriber (Fast DDS, the Python the tests use, `FDAVAR_PYTHON` or
//!   `.venv`; left out, saying so, when rclpy is not there) with `qos_profile_sensor_data`, counting in its callback: what a
//!   ROS 2 user's own Python node pays for the same topic before doing anything with it. Not by
//!   default: it takes most of a core, which changes what the others' wake-ups cost.
//!
//! `FDAVAR_NODE=PATH` runs that build of the node instead (interleaved A/B runs against a copy
//! of the previous build).
//!
//! Not a test: numbers depend on the machine; nothing is asserted.

#[path = "../tests/common/mod.rs"]
mod common;

use fdavar::msgs::diagnostic_msgs::DiagnosticArray;
use fdavar::msgs::sensor_msgs::Imu;
use fdavar::ros::node::{peer_node, publish_on, spin_in_background, subscribe_on, wait_for_subscribers};
use fdavar::signal::ImuSample;
use ros2_client::qos::{History, Reliability};
use ros2_client::QosProfile;
use std::io::Read;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

const DOMAIN: u16 = 90;

/// The user + system ticks of a /proc `stat` file (a process's or a thread's), and its name.
fn stat_ticks(path: &str) -> Option<(String, u64)> {
    let stat = std::fs::read_to_string(path).ok()?;
    // Fields after the command name (which may hold spaces) start after the last ')'.
    let name = stat[stat.find('(')? + 1..stat.rfind(')')?].to_string();
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of stat, i.e. 11 and 12 after the state field.
    let ticks = fields.get(11)?.parse::<u64>().ok()? + fields.get(12)?.parse::<u64>().ok()?;
    Some((name, ticks))
}

fn cpu_ticks(pid: u32) -> Option<u64> {
    stat_ticks(&format!("/proc/{pid}/stat")).map(|(_, t)| t)
}

/// One thread of the node: its id, name, user + system ticks, and how often it went to sleep
/// (`voluntary_ctxt_switches`: each such sleep ends in a wake-up, the host's dearest event).
struct ThreadUse {
    tid: String,
    name: String,
    ticks: u64,
    sleeps: u64,
}

/// Each thread of `pid`.
fn thread_use(pid: u32) -> Vec<ThreadUse> {
    let Ok(dir) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return Vec::new();
    };
    dir.flatten()
        .filter_map(|e| {
            let tid = e.file_name().to_string_lossy().into_owned();
            let (name, ticks) = stat_ticks(&format!("/proc/{pid}/task/{tid}/stat"))?;
            let sleeps = common::voluntary_switches(pid, &tid)?;
            Some(ThreadUse { tid, name, ticks, sleeps })
        })
        .collect()
}

/// The calling thread's CPU time in seconds (`CLOCK_THREAD_CPUTIME_ID`).
fn thread_cpu_s() -> f64 {
    let mut t = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes only the timespec it is given.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
}

/// Pins the calling thread to one CPU (`sched_setaffinity`); false if refused.
fn pin_to_cpu(cpu: usize) -> bool {
    // SAFETY: the set is zeroed and filled by the libc macros; sched_setaffinity(0, …) changes
    // only the calling thread.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) == 0
    }
}

/// µs of CPU per wake-up of a thread that sleeps `sleep` at a time, with a timer slack of 1 ns
/// as the node's receive thread has between batches.
fn timer_wake_price(sleep: Duration, seconds: f64) -> f64 {
    std::thread::spawn(move || {
        // SAFETY: PR_SET_TIMERSLACK changes only the calling thread's timer slack.
        unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong) };
        let (cpu0, start) = (thread_cpu_s(), Instant::now());
        let mut wakes = 0u64;
        while start.elapsed().as_secs_f64() < seconds {
            std::thread::sleep(sleep);
            wakes += 1;
        }
        (thread_cpu_s() - cpu0) / wakes as f64 * 1e6
    })
    .join()
    .expect("timer thread")
}

/// µs of CPU per wake-up of a thread blocked in `recv` on a UDP socket, woken by each of
/// `rate_hz` datagrams of an IMU message's size sent by another thread, paced as the bench paces
/// its IMU messages: what any subscriber, DDS or not, pays per message before it reads a byte.
/// The receiver and the sender are pinned to `cpus` (receiver, sender); NaN if the host refuses.
fn datagram_wake_price(rate_hz: f64, seconds: f64, cpus: (usize, usize)) -> f64 {
    let receiver = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind a UDP socket");
    let address = receiver.local_addr().expect("its address");
    let received = std::thread::spawn(move || {
        let pinned = pin_to_cpu(cpus.0);
        let mut buffer = [0u8; 2048];
        let mut cpu0 = None;
        let mut wakes = 0u64;
        loop {
            match receiver.recv(&mut buffer) {
                Ok(1) => break, // the sender's end mark
                Ok(_) => {
                    // Timed from the first datagram: the thread's start is not a wake-up.
                    cpu0.get_or_insert_with(thread_cpu_s);
                    wakes += 1;
                }
                Err(e) => panic!("recv: {e}"),
            }
        }
        let price = (thread_cpu_s() - cpu0.unwrap_or(0.0)) / wakes.saturating_sub(1).max(1) as f64 * 1e6;
        if pinned { price } else { f64::NAN }
    });
    let sender_pinned = std::thread::spawn(move || {
        let pinned = pin_to_cpu(cpus.1);
        let sender = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind a UDP socket");
        let payload = [0x5au8; 400]; // about a sensor_msgs/Imu in one RTPS DATA datagram
        let period = Duration::from_secs_f64(1.0 / rate_hz);
        let start = Instant::now();
        for k in 0..(seconds * rate_hz) as u64 {
            if let Some(wait) = (start + period.mul_f64(k as f64)).checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
            sender.send_to(&payload, address).expect("send");
        }
        sender.send_to(&[1], address).expect("send the end mark");
        pinned
    })
    .join()
    .expect("sender thread");
    let price = received.join().expect("receiver thread");
    if sender_pinned { price } else { f64::NAN }
}

/// The `rclpy` peer: counts `/imu` in its callback (sensor-data QoS, as a ROS 2 user's IMU
/// subscriber would); prints the count when its stdin closes.
const RCLPY_PEER: &str = r#"
import os, sys, threading, rclpy
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Imu
rclpy.init()
node = rclpy.create_node("fdavar_bench_rclpy")
count = [0]
def on_imu(msg):
    count[0] += 1
node.create_subscription(Imu, "/imu", on_imu, qos_profile_sensor_data)
def report():
    sys.stdin.read()
    print(count[0], flush=True)
    os._exit(0)
threading.Thread(target=report, daemon=True).start()
rclpy.spin(node)
"#;

/// The `bare` peer (this bench run with `--bare-subscriber`): the node's IMU subscription at its
/// defaults (best effort, keep last 100), each message taken and decoded as DDS wakes the thread
/// and only counted; prints the count when its stdin closes.
fn bare_subscriber() {
    let mut node = peer_node(DOMAIN, "fdavar_bench_bare").expect("node");
    let qos = QosProfile::subscription_default()
        .reliability(Reliability::BestEffort)
        .history(History::KeepLast { depth: 100 });
    let imu = subscribe_on::<Imu>(&mut node, "/imu", &qos).expect("subscription");
    spin_in_background(&mut node).expect("spinner");
    let count = Arc::new(AtomicU64::new(0));
    let reported = Arc::clone(&count);
    std::thread::spawn(move || {
        let _ = std::io::copy(&mut std::io::stdin(), &mut std::io::sink());
        println!("{}", reported.load(Ordering::Relaxed));
        std::process::exit(0);
    });
    for read in futures::executor::block_on_stream(Box::pin(imu.async_stream())) {
        if read.is_ok() {
            count.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// A subscriber measured beside the node (PEERS).
struct Peer {
    name: &'static str,
    child: Child,
    ticks0: u64,
}

/// Starts the peers named in `list` (`bare`, `rclpy`, comma-separated; `none`), saying why one is
/// left out.
fn start_peers(list: &str) -> Vec<Peer> {
    let mut peers = Vec::new();
    for name in list.split(',').filter(|n| !n.is_empty() && *n != "none") {
        let mut cmd = match name {
            "bare" => {
                let mut c = Command::new(std::env::current_exe().expect("the bench's path"));
                c.arg("--bare-subscriber");
                c
            }
            "rclpy" => {
                // Without rclpy the peer is left out, python_with saying why.
                let Some(python) = common::python_with("import rclpy, sensor_msgs.msg", ".ci/python-ros.txt") else {
                    continue;
                };
                let mut c = Command::new(python);
                c.args(["-c", RCLPY_PEER]).env("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp");
                c
            }
            other => panic!("unknown peer {other:?}: bare, rclpy or none"),
        };
        let child = cmd
            .env("ROS_DOMAIN_ID", DOMAIN.to_string())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("start the {name} peer: {e}"));
        let name = if name == "bare" { "bare ros2-client subscriber" } else { "rclpy subscriber" };
        peers.push(Peer { name, child, ticks0: 0 });
    }
    peers
}

fn main() {
    if std::env::args().any(|a| a == "--bare-subscriber") {
        return bare_subscriber();
    }
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let rate_hz: f64 = args.first().and_then(|a| a.parse().ok()).unwrap_or(2000.0);
    let seconds: f64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(20.0);
    let diagnosis_s: f64 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(10.0);
    let diagnosis = format!("diagnosis_period_s:={diagnosis_s:?}");
    let sinusoid: f64 = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(0.0);
    let share: f64 = args.get(4).and_then(|a| a.parse().ok()).unwrap_or(0.005);
    let share_param = format!("diagnosis_cpu_share:={share:?}");
    let batch_ms: f64 = args.get(5).and_then(|a| a.parse().ok()).unwrap_or(0.8);
    let batch_param = format!("receive_batch_ms:={batch_ms:?}");
    let mut peers = start_peers(args.get(6).map_or("bare", String::as_str));

    // FDAVAR_NODE runs another build (e.g. a copy of the previous one, for interleaved A/B runs).
    let binary =
        std::env::var("FDAVAR_NODE").unwrap_or_else(|_| env!("CARGO_BIN_EXE_fdavar_node").into());
    let mut child = Command::new(&binary)
        .args([
            "--ros-args",
            "-p",
            "publish_rate_hz:=2.0",
            "-p",
            &diagnosis,
            "-p",
            &share_param,
            "-p",
            &batch_param,
            // The bench reads /diagnostics 1.5 s after its last message: not stale yet.
            "-p",
            "stale_timeout_s:=5.0",
            "--log-level",
            "warn",
        ])
        .env("ROS_DOMAIN_ID", DOMAIN.to_string())
        .stdout(Stdio::null())
        .spawn()
        .expect("start fdavar_node");
    let pid = child.id();

    let mut node = peer_node(DOMAIN, "fdavar_bench").expect("node");
    let imu_qos = QosProfile::subscription_default().history(History::KeepLast { depth: 100 });
    let imu = publish_on::<Imu>(&mut node, "/imu", &imu_qos).expect("imu publisher");
    let diag_qos = QosProfile::publisher_default().history(History::KeepLast { depth: 10 });
    let diagnostics = subscribe_on::<DiagnosticArray>(&mut node, "/diagnostics", &diag_qos)
        .expect("subscription");
    spin_in_background(&mut node).expect("spinner");
    assert!(
        wait_for_subscribers(&imu, &node, 1 + peers.len(), Duration::from_secs(30)),
        "fdavar_node or a peer never matched the IMU publisher"
    );
    std::thread::sleep(Duration::from_millis(500));

    let period = Duration::from_secs_f64(1.0 / rate_hz);
    let n = (seconds * rate_hz) as u64;
    let ticks0 = cpu_ticks(pid).expect("read /proc");
    let threads0 = thread_use(pid);
    for peer in &mut peers {
        peer.ticks0 = cpu_ticks(peer.child.id()).expect("read /proc");
    }
    let start = Instant::now();
    let mut x = 0x2545_f491_4f6c_dd1d_u64;
    for k in 0..n {
        let due = start + period.mul_f64(k as f64);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        // xorshift noise: deterministic and cheap.
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let v = (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        let t = k as f64 / rate_hz;
        let hidden = sinusoid * (2.0 * std::f64::consts::PI * 2.0 * t).sin();
        // One noise value on every axis: each gyro axis is a multiple of accel_x (gyro_x
        // 0.1 s × accel_x), so the diagnosis rightly names `g_sensitivity` (the printed
        // suggestions): not a false alarm.
        let sample = ImuSample {
            stamp_ns: 1_000_000_000 + (k as f64 * 1e9 / rate_hz) as i64,
            gyro: [1e-3 * v + hidden, -1e-3 * v, 2e-3 * v],
            accel: [1e-2 * v, 0.0, 9.81],
        };
        let _ = imu.publish(Imu::from_sample(&sample, "imu_link").unwrap());
    }
    let wall = start.elapsed().as_secs_f64();
    let ticks1 = cpu_ticks(pid).expect("read /proc");
    let cpu_s = (ticks1 - ticks0) as f64 / 100.0; // USER_HZ = 100 on Linux
    let peer_lines: Vec<String> = peers
        .iter_mut()
        .map(|peer| {
            let ticks = cpu_ticks(peer.child.id()).expect("read /proc") - peer.ticks0;
            drop(peer.child.stdin.take()); // the peer prints its count and exits
            let mut count = String::new();
            let _ = peer.child.stdout.take().expect("piped").read_to_string(&mut count);
            let _ = peer.child.wait();
            format!(
                "  {}, the same minutes: CPU {:.1} % of one core, counted {}",
                peer.name,
                ticks as f64 / wall,
                count.trim()
            )
        })
        .collect();
    // (name, share of a core in %, wake-ups per second)
    let mut per_thread: Vec<(String, f64, f64)> = thread_use(pid)
        .into_iter()
        .map(|t| {
            let before = threads0.iter().find(|b| b.tid == t.tid);
            let share = (t.ticks - before.map_or(0, |b| b.ticks)) as f64 / 100.0 / wall * 100.0;
            let wakes = (t.sleeps - before.map_or(0, |b| b.sleeps)) as f64 / wall;
            (t.name, share, wakes)
        })
        .filter(|(_, share, _)| *share > 0.0)
        .collect();
    per_thread.sort_by(|a, b| b.1.total_cmp(&a.1));
    // The latest /diagnostics after the node has published at least once more.
    std::thread::sleep(Duration::from_millis(1500));
    let mut last = None;
    while let Ok(Some((msg, _))) = diagnostics.take() {
        last = Some(msg);
    }
    let _ = child.kill();
    let _ = child.wait();
    let Some(array) = last else {
        eprintln!("no /diagnostics received");
        std::process::exit(1);
    };
    let gx = &array.status[0];
    let get = |k: &str| {
        gx.values
            .iter()
            .find(|v| v.key == k)
            .map_or("?", |v| v.value.as_str())
    };
    println!(
        "fdavar_node at {rate_hz} Hz for {wall:.1} s: sent {n}, counted {} samples, {} drops; \
         CPU {:.1} % of one core; receive-to-update latency p50 {} ms, p99 {} ms; diagnosis \
         every {diagnosis_s} s (CPU share {share}, batches of {batch_ms} ms, gyro_x sinusoid {sinusoid} rad/s), last one on gyro_x {} ms, \
         suggestions [{}]",
        get("samples"),
        get("drops"),
        100.0 * cpu_s / wall,
        get("latency_p50_ms"),
        get("latency_p99_ms"),
        get("diagnosis_ms"),
        get("suggestions"),
    );
    let threads: Vec<String> = per_thread
        .iter()
        .map(|(name, share, wakes)| format!("{name} {share:.2} % ({wakes:.0} wake-ups/s)"))
        .collect();
    println!("  per thread: {} ({binary})", threads.join(", "));
    for line in peer_lines {
        println!("{line}");
    }
    // What the host charges for the node's kinds of wake-up, measured in the same minutes by
    // threads that do nothing else (the node and the peers gone). On a virtual machine a wake-up
    // of an idle virtual CPU costs several times a bare-metal one, and the node's share is mostly
    // its wake-ups' price (docs/ros.md, "Threads").
    let timer_us = timer_wake_price(Duration::from_secs_f64(batch_ms.max(0.1) * 1e-3), 10.0);
    let same_us = datagram_wake_price(rate_hz, 10.0, (0, 0));
    let cross_us = datagram_wake_price(rate_hz, 10.0, (1, 0)); // NaN on a single CPU
    println!(
        "  this host's price of a wake-up, the same minutes (threads that do nothing else, 10 s \
         each): {timer_us:.1} µs of CPU after a {:.1} ms sleep; {same_us:.1} µs per datagram at \
         {rate_hz} Hz on the sender's CPU, {cross_us:.1} µs on another CPU",
        batch_ms.max(0.1),
    );
    // Threads woken often: their CPU per wake-up, to hold against the prices above (the rest
    // of a wake-up's cost is the thread's own work on the messages it found).
    let per_wake: Vec<String> = per_thread
        .iter()
        .filter(|(_, _, wakes)| *wakes >= 100.0)
        .map(|(name, share, wakes)| format!("{name} {:.1} µs", share * 1e4 / wakes))
        .collect();
    println!("    the node's CPU per wake-up: {}", per_wake.join(", "));
}
