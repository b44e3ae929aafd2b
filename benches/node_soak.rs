//! Soak benchmark of `fdavar_node`: a long recording replayed faster than real time; the node's
//! memory over the run, and its final whole-run answer against `fdavar diagnose` on the recording.
//!
//! ```text
//! cargo bench --bench node_soak -- dds [HOURS] [DIAGNOSIS_PERIOD_S] [RATE]
//! cargo bench --bench node_soak -- hostile [HOURS] [DIAGNOSIS_PERIOD_S] [RATE]
//! cargo bench --bench node_soak -- in-process [HOURS] [DIAGNOSIS_PERIOD_S] [hostile]
//! cargo bench --bench node_soak -- recording [HOURS] [DIR] [hostile]
//! ```
//! (defaults: 24 h, a diagnosis round every 1800 s of recording time, `--rate 100`).
//!
//! `dds`: `fdavar simulate` writes HOURS of bags/specs/clean.yaml at 100 Hz (MCAP); `fdavar play
//! --clock --reliable` replays it into the release `fdavar_node` on sim time (ROS_DOMAIN_ID 86). Every
//! wall second the bench reads the node's VmRSS (/proc/PID/status) and the `samples` count of its
//! `/diagnostics`, and prints the RSS at each recorded hour. After the replay it publishes one
//! `/clock` a diagnosis period past the last one, so that a last round diagnoses every message;
//! then for each axis the published `model`, `fit_error`, every coefficient and `suggestions` must
//! equal `fdavar diagnose BAG --json --first N --axis A` (N: the node's `diagnosed_messages`),
//! exactly (/diagnostics carries each f64 in full, `{}` formatting).
//!
//! `hostile` (issue 13): the same replay of a recording with faults written into it (see
//! [`inject_faults`]: NaN bursts, ±1e300 values, duplicated and zero stamps every hour, a publisher
//! restart whose clock is 30 s behind at 40 % of the run, a clock jump 13 h forward at 70 %),
//! then a flood: a second `fdavar play` of 100 000 earlier messages at 1000× (about 10⁵
//! messages/s). Every message must be accounted for: the node's `received + drops` equals what
//! the players sent, after the replay and after the flood; the whole-run answer equals offline
//! on the faulty recording; and the node still publishes after the flood.
//!
//! `recording`: writes the recording `dds` (or with `hostile`, the faulty one) replays into DIR
//! and stops: `fdavar diagnose DIR/faulty --first N` is then the node's round after N messages,
//! to profile one round offline (e.g. under heaptrack).
//!
//! `in-process`: the node's engine and monitor (`AnalysisEngine` + `Monitor`, what the node's
//! analysis thread runs) fed HOURS of white noise + random walk at 100 Hz from this process, a
//! report every recorded second; the RSS is this process's. No DDS, no bag: the memory curve of
//! the analysis alone, in a few minutes. With `hostile`, the samples carry the faults of the
//! `hostile` mode at the same messages ([`hostile_clock_offset_ns`], [`hostile_hourly_fault`]),
//! each received at its unshifted stamp (the replay's clock).
//!
//! Flat means, past 6 h (the whole-run record's cap of 2²⁰ samples per axis is reached at 2.9 h at 100 Hz):
//! the RSS between diagnosis rounds does not grow (the median of the per-second RSS samples of the
//! last third of the run exceeds that of the first third by less than 5 %), and no round needs
//! more memory than the rounds of the first third did (the kernel's high-water mark VmHWM at the
//! end exceeds its value at the end of the first third by less than 5 %) ([`Curve::verdict`]).
//! The bench exits 1 when memory is not flat or live ≠ offline. Numbers depend on the machine;
//! 24 h take about 15 min (`dds`: 866 s of replay measured).

use fdavar::msgs::builtin_interfaces::Time;
use fdavar::msgs::diagnostic_msgs::DiagnosticArray;
use fdavar::msgs::rosgraph_msgs::Clock;
use fdavar::ros::node::{peer_node, publish_on, spin_in_background, subscribe_on};
use ros2_client::qos::{History, WhenFull};
use ros2_client::QosProfile;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const DOMAIN: u16 = 86;
const RATE_HZ: u64 = 100;
const AXES: [&str; 6] = [
    "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z",
];

/// A memory figure of a process from /proc/PID/status (`VmRSS`, `VmHWM`: kB there), MB.
fn status_mb(pid: &str, field: &str) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.split(':').next() == Some(field))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Memory samples (messages seen, RSS MB, VmHWM MB) over a run, printed per recorded hour.
#[derive(Default)]
struct Curve {
    points: Vec<(u64, f64, f64)>,
    next_hour: u64,
}

impl Curve {
    /// Adds a sample of the process `pid`'s memory after `messages` messages.
    fn sample(&mut self, pid: &str, messages: u64, elapsed_s: f64) {
        let mb = |field| status_mb(pid, field).unwrap_or(f64::NAN);
        let (rss, hwm) = (mb("VmRSS"), mb("VmHWM"));
        self.points.push((messages, rss, hwm));
        let per_hour = 3600 * RATE_HZ;
        while messages >= self.next_hour * per_hour {
            if self.next_hour > 0 {
                println!(
                    "  {:>2} h: {:>9} messages, RSS {rss:7.1} MB, high-water mark {hwm:7.1} MB  ({elapsed_s:.0} s wall)",
                    self.next_hour, messages
                );
            }
            self.next_hour += 1;
        }
    }

    /// Prints the figure; true when flat.
    ///
    /// The RSS sampled once a wall second swings by a hundred MB and more while a whole-run
    /// diagnosis runs (its buffers are transient), so one sample at 6 h against one at the end
    /// says little. Flat means, over the first and the last third of the run after 6 h (past the
    /// record's cap): the median of the samples (the level between rounds) grows by less than
    /// 5 %, and so does the high-water mark from the end of the first third to the end (no round
    /// needs more than the first third's did). Why not the largest sample: a round's largest
    /// buffers live for well under a second and their size follows the record's length at that
    /// round (2¹⁹ to 2²⁰ values, then halved), so which of the once-a-second samples fall on a
    /// peak is luck (measured at 32c5f88: largest sample 243.8 MB in 6–12 h, 280.0 MB in
    /// 18–24 h, medians 129.8 and 132.8 MB). The largest sample is still printed.
    fn verdict(&self, total: u64) -> bool {
        let six_h = 6 * 3600 * RATE_HZ;
        let end = self.points.last().map_or(f64::NAN, |p| p.1);
        let hwm_end = self.points.last().map_or(f64::NAN, |p| p.2);
        let max_all = self.points.iter().map(|p| p.1).fold(f64::NAN, f64::max);
        if total <= six_h {
            println!("RSS at the end {end:.1} MB, max {max_all:.1} MB (too short for the 6 h figure)");
            return true;
        }
        let third = (total - six_h) / 3;
        let window = |from: u64, to: u64| -> (f64, f64, f64, usize) {
            let mut v: Vec<f64> = self
                .points
                .iter()
                .filter(|p| p.0 >= from && p.0 <= to)
                .map(|p| p.1)
                .collect();
            v.sort_by(f64::total_cmp);
            let n = v.len();
            if n == 0 {
                return (f64::NAN, f64::NAN, f64::NAN, 0);
            }
            (v[0], v[n / 2], v[n - 1], n)
        };
        let hours = |m: u64| m as f64 / (3600 * RATE_HZ) as f64;
        let (e_min, e_med, e_max, e_n) = window(six_h, six_h + third);
        let (l_min, l_med, l_max, l_n) = window(total - third, total);
        let hwm_early = self
            .points
            .iter()
            .take_while(|p| p.0 <= six_h + third)
            .last()
            .map_or(f64::NAN, |p| p.2);
        let growth = |late: f64, early: f64| 100.0 * (late / early - 1.0);
        let flat = growth(l_med, e_med) < 5.0 && growth(hwm_end, hwm_early) < 5.0;
        println!(
            "RSS, {:.0}–{:.0} h ({e_n} samples): min {e_min:.1}, median {e_med:.1}, max {e_max:.1} MB; \
             {:.0}–{:.0} h ({l_n} samples): min {l_min:.1}, median {l_med:.1}, max {l_max:.1} MB; \
             high-water mark {hwm_early:.1} MB at {:.0} h, {hwm_end:.1} MB at the end; \
             median {:+.1} %, high-water mark {:+.1} % (flat: both < 5 %: {}); largest sample {:+.1} %; \
             at the end {end:.1} MB, largest sample overall {max_all:.1} MB",
            hours(six_h),
            hours(six_h + third),
            hours(total - third),
            hours(total),
            hours(six_h + third),
            growth(l_med, e_med),
            growth(hwm_end, hwm_early),
            if flat { "yes" } else { "NO" },
            growth(l_max, e_max),
        );
        flat
    }
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let mode = args.first().map_or("dds", String::as_str);
    let hours: f64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(24.0);
    let period_s: f64 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(1800.0);
    let ok = match mode {
        "dds" | "hostile" => {
            let rate: f64 = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(100.0);
            dds(hours, period_s, rate, mode == "hostile")
        }
        "in-process" => in_process(hours, period_s, args.get(3).is_some_and(|a| a == "hostile")),
        "recording" => {
            let out = args.get(2).map_or("soak_recording", String::as_str);
            let hostile = args.get(3).is_some_and(|a| a == "hostile");
            std::fs::create_dir_all(out).expect("create the output directory");
            let (bag, total) = soak_recording(Path::new(out), hours, hostile);
            println!("{total} IMU messages in {}", bag.display());
            true
        }
        other => {
            eprintln!("node_soak: unknown mode {other:?} (dds, hostile, in-process or recording)");
            false
        }
    };
    if !ok {
        std::process::exit(1);
    }
}

/// The node's engine and monitor in this process (see the module doc).
fn in_process(hours: f64, period_s: f64, hostile: bool) -> bool {
    use fdavar::model::ModelSpec;
    use fdavar::ros::engine::AnalysisEngine;
    use fdavar::ros::monitor::{Monitor, MonitorSettings};
    use fdavar::signal::ImuSample;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    // The node's allocator settings, for the node's memory curve.
    fdavar::analysis::return_large_buffers_to_kernel();

    let config = fdavar::params::config_from_params(&Default::default()).unwrap();
    let engine = AnalysisEngine::new(
        config,
        ModelSpec::parse("N,B,K").unwrap(),
        Default::default(),
        fdavar::model::record::RecordBuilder::DEFAULT_MAX_SAMPLES,
    )
    .unwrap();
    // Rounds paced by recording time alone (no CPU budget), as the soak has always run them.
    let settings = MonitorSettings {
        diagnosis_period_s: period_s,
        stale_timeout_s: 10.0,
        diagnosis_cpu_share: 1.0,
        ..MonitorSettings::default()
    };
    let mut monitor = Monitor::new(settings, Some(Box::new(engine)));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(24);
    let normal = Normal::new(0.0, 1.0).unwrap();
    let total = (hours * 3600.0) as u64 * RATE_HZ;
    let pid = std::process::id().to_string();
    let mut curve = Curve::default();
    let mut walk = [0.0; 6];
    let start = Instant::now();
    println!(
        "in-process engine + monitor: {hours} h at {RATE_HZ} Hz, diagnosis every {period_s} s{}",
        if hostile { ", with the hostile mode's faults" } else { "" }
    );
    for k in 0..total {
        let mut v = [0.0; 6];
        for (x, w) in v.iter_mut().zip(walk.iter_mut()) {
            *w += 1e-5 * normal.sample(&mut rng);
            *x = 1e-3 * normal.sample(&mut rng) + *w;
        }
        let stamp_ns = 1_700_000_000_000_000_000 + (k * 1_000_000_000 / RATE_HZ) as i64;
        let mut sample = ImuSample {
            stamp_ns,
            gyro: [v[0], v[1], v[2]],
            accel: [v[3], v[4], v[5]],
        };
        let mut copies = 1;
        if hostile {
            sample.stamp_ns += hostile_clock_offset_ns(k, total);
            copies = hostile_hourly_fault(k, &mut sample).map_or(1, Fault::copies);
        }
        for _ in 0..copies {
            monitor.push(sample, "imu_link", stamp_ns);
        }
        if (k + 1) % RATE_HZ == 0 {
            monitor.report(stamp_ns);
        }
        if (k + 1) % (60 * RATE_HZ) == 0 || k + 1 == total {
            curve.sample(&pid, k + 1, start.elapsed().as_secs_f64());
        }
    }
    let wall = start.elapsed().as_secs_f64();
    println!(
        "{total} messages in {wall:.1} s wall ({:.0}× real time)",
        total as f64 / RATE_HZ as f64 / wall
    );
    curve.verdict(total)
}

/// Writes the recording `dds` and `hostile` replay into `dir`: HOURS of bags/specs/clean.yaml
/// at 100 Hz (`fdavar simulate`), with [`inject_faults`] when `hostile`. Returns the bag and its
/// IMU message count (the faults add duplicated messages).
fn soak_recording(dir: &Path, hours: f64, hostile: bool) -> (std::path::PathBuf, u64) {
    let clean = dir.join("soak");
    let total = (hours * 3600.0) as u64 * RATE_HZ;
    let spec = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/bags/specs/clean.yaml"
    ))
    .expect("bags/specs/clean.yaml")
    .replace(
        "duration_s: 120",
        &format!("duration_s: {}", total / RATE_HZ),
    );
    let spec_path = dir.join("soak.yaml");
    std::fs::write(&spec_path, spec).unwrap();
    let t0 = Instant::now();
    let made = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args([
            "simulate",
            spec_path.to_str().unwrap(),
            "--out",
            clean.to_str().unwrap(),
        ])
        .output()
        .expect("run fdavar simulate");
    assert!(
        made.status.success(),
        "{}",
        String::from_utf8_lossy(&made.stderr)
    );
    println!(
        "simulated {hours} h at {RATE_HZ} Hz ({total} messages) in {:.1} s",
        t0.elapsed().as_secs_f64()
    );
    let bag = if hostile {
        let faulty = dir.join("faulty");
        let injected = inject_faults(&clean, &faulty, total);
        println!("faults written: {injected}");
        faulty
    } else {
        clean
    };
    let total = fdavar::bag::BagReader::open(&bag)
        .expect("open the replayed bag")
        .imu_topic(None)
        .expect("its IMU topic")
        .message_count;
    (bag, total)
}

/// `fdavar play` into `fdavar_node` over DDS (see the module doc).
fn dds(hours: f64, period_s: f64, rate: f64, hostile: bool) -> bool {
    let dir = tempfile::tempdir().expect("temporary directory");
    let (bag, total) = soak_recording(dir.path(), hours, hostile);

    let diagnosis = format!("diagnosis_period_s:={period_s:?}");
    // The forced last round comes one period after the last /clock: not stale by then (the
    // longest stale_timeout_s the node takes is 3600 s).
    assert!(
        period_s <= 3000.0,
        "DIAGNOSIS_PERIOD_S must be at most 3000 s"
    );
    let stale = "stale_timeout_s:=3600.0";
    let mut node = Command::new(env!("CARGO_BIN_EXE_fdavar_node"))
        .args([
            "--ros-args",
            // bags/specs/clean.yaml records on /imu/data.
            "-r",
            "imu:=/imu/data",
            "-p",
            "use_sim_time:=true",
            "-p",
            "qos.reliable:=true",
            "-p",
            &diagnosis,
            // Rounds paced by recording time alone (no CPU budget), so that the last forced
            // round comes when the bench waits for it.
            "-p",
            "diagnosis_cpu_share:=1.0",
            "-p",
            "publish_rate_hz:=1.0",
            "-p",
            stale,
            // A diagnosis of one axis of a full record takes about a second, while the replay
            // goes on: room for 10 s of messages at 10 000 a second (preallocated: a constant).
            "-p",
            "queue_size:=100000",
            // Keep last 100 (the default) loses messages whenever the receive thread is late by
            // 100 (another process on the core): the replay must reach the node whole.
            "-p",
            "qos.depth:=10000",
            "--log-level",
            "warn",
        ])
        .env("ROS_DOMAIN_ID", DOMAIN.to_string())
        .stdout(Stdio::null())
        .spawn()
        .expect("start fdavar_node");
    let pid = node.id().to_string();

    let mut ros = peer_node(DOMAIN, "fdavar_soak").expect("node");
    let diag_qos = QosProfile::publisher_default().history(History::KeepLast { depth: 10 });
    let diagnostics =
        subscribe_on::<DiagnosticArray>(&mut ros, "/diagnostics", &diag_qos).expect("subscription");
    let clock_qos = QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Wait(Duration::from_millis(100)))
        .history(History::KeepLast { depth: 1 });
    let clock_out = publish_on::<Clock>(&mut ros, "/clock", &clock_qos).expect("publisher");
    spin_in_background(&mut ros).expect("spinner");

    let start = Instant::now();
    let mut player = play(&bag, rate, true);
    println!("replaying with fdavar play --clock --reliable --rate {rate} into fdavar_node (diagnosis every {period_s} s):");

    let mut last: Option<DiagnosticArray> = None;
    let mut curve = Curve::default();
    let drain = |last: &mut Option<DiagnosticArray>| loop {
        match diagnostics.take() {
            Ok(Some((msg, _))) => *last = Some(msg),
            Ok(None) => break,
            Err(e) => {
                eprintln!("DEBUG diagnostics take: {e:?}");
                break;
            }
        }
    };
    // Messages that reached the node: taken off DDS, or refused by its full queue.
    let samples = |a: &Option<DiagnosticArray>| -> u64 {
        let count = |key| {
            a.as_ref()
                .and_then(|a| value(&a.status[0].values, key))
                .and_then(|v| v.parse::<u64>().ok())
                .unwrap_or(0)
        };
        count("received") + count("drops")
    };
    // Drains /diagnostics every `pause` until `done` holds or `secs` pass; `each` runs before
    // every pause.
    let wait = |last: &mut Option<DiagnosticArray>,
                secs: u64,
                pause: Duration,
                each: &mut dyn FnMut(),
                done: &dyn Fn(&Option<DiagnosticArray>) -> bool| {
        let by = Instant::now() + Duration::from_secs(secs);
        while Instant::now() < by && !done(last) {
            each();
            std::thread::sleep(pause);
            drain(last);
        }
    };
    let played = loop {
        std::thread::sleep(Duration::from_secs(1));
        drain(&mut last);
        curve.sample(&pid, samples(&last), start.elapsed().as_secs_f64());
        if let Some(status) = player.try_wait().expect("wait for fdavar play") {
            break status;
        }
    };
    let play_wall = start.elapsed().as_secs_f64();
    let said = played_said(&mut player, played);
    let mut sent = imu_sent(&said);

    // Every message analysed, then one /clock a period later: a last round over all of them.
    let second = Duration::from_secs(1);
    wait(&mut last, 120, second, &mut || {}, &|l| samples(l) >= total);
    // /diagnostics is stamped with the node's time: the last /clock it took.
    let node_time = last.as_ref().map_or(0, |a| a.header.stamp.to_ns());
    let end_clock = node_time + (period_s * 1e9) as i64 + 1_000_000_000;
    for _ in 0..3 {
        // The node's /clock reader is best effort: say it more than once.
        let _ = clock_out.publish(Clock {
            clock: Time::from_ns(end_clock).unwrap(),
        });
        std::thread::sleep(Duration::from_millis(200));
    }
    let diagnosed = |a: &DiagnosticArray, i: usize| -> u64 {
        value(&a.status[i].values, "diagnosed_messages")
            .and_then(|v| v.parse().ok())
            .unwrap_or(0)
    };
    wait(&mut last, 120, second, &mut || {}, &|l| {
        l.as_ref().is_some_and(|a| (0..6).all(|i| diagnosed(a, i) == total))
    });
    curve.sample(&pid, samples(&last), start.elapsed().as_secs_f64());
    let hwm = curve.points.last().map_or(f64::NAN, |p| p.2);
    let array = last.clone().expect("no /diagnostics received");
    let mut accounted = samples(&last) == sent;
    println!(
        "accounting after the replay: sent {sent}, node received + drops {} ({})",
        samples(&last),
        if accounted { "every message accounted for" } else { "MISSING" }
    );

    if hostile {
        // A second publisher floods 100 000 messages from the start of the recording (older
        // stamps: a restarted driver) at 1000× (about 10⁵ messages/s).
        let flood = dir.path().join("flood");
        copy_first(&dir.path().join("soak"), &flood, 100_000);
        let mut flooder = play(&flood, 1000.0, false);
        let flooded = flooder.wait().expect("wait for the flood");
        sent += imu_sent(&played_said(&mut flooder, flooded));
        // Node time moves on (sim time): the next publications count the flood.
        let before = array.header.stamp.to_ns();
        let mut k = 2;
        let mut tick = || {
            let _ = clock_out.publish(Clock {
                clock: Time::from_ns(end_clock + k * 1_000_000_000).unwrap(),
            });
            k += 1;
        };
        wait(&mut last, 60, Duration::from_millis(500), &mut tick, &|l| {
            samples(l) == sent && l.as_ref().is_some_and(|a| a.header.stamp.to_ns() > before)
        });
        let after = last.as_ref().expect("diagnostics");
        let published = after.header.stamp.to_ns() > before;
        println!(
            "after the flood: sent {sent} in all, node received + drops {} (drops {}); still \
             publishing: {}",
            samples(&last),
            value(&after.status[0].values, "drops").unwrap_or("?"),
            if published { "yes" } else { "NO" }
        );
        accounted &= samples(&last) == sent && published;
    }
    let _ = node.kill();
    let _ = node.wait();

    let drops = value(&array.status[0].values, "drops")
        .unwrap_or("?")
        .to_string();
    println!(
        "{} in {play_wall:.0} s wall ({:.1}× real time); node counted {} samples, {drops} \
         drops; node peak (VmHWM) {hwm:.1} MB",
        said.lines()
            .find(|l| l.contains(" IMU "))
            .unwrap_or("")
            .trim(),
        total as f64 / RATE_HZ as f64 / play_wall,
        samples(&Some(array.clone())),
    );
    let flat = curve.verdict(total);

    let mut equal = true;
    for (i, axis) in AXES.iter().enumerate() {
        let status = &array.status[i];
        let n = diagnosed(&array, i);
        let offline = offline(&bag, n, axis);
        let differences = compare(&status.values, &offline);
        println!(
            "{axis}: diagnosed_messages {n}, fit_error live {} offline {}, {} coefficients: {}",
            value(&status.values, "fit_error").unwrap_or("?"),
            offline["fit_error"].as_str().unwrap_or("?"),
            offline["coefficients"].as_object().map_or(0, |c| c
                .values()
                .map(|e| e.as_object().map_or(0, |e| e.len()))
                .sum()),
            if differences.is_empty() {
                "live = offline".to_string()
            } else {
                differences.join("; ")
            }
        );
        equal &= differences.is_empty() && n == total;
    }
    flat && equal && accounted
}

/// `fdavar play BAG --reliable --rate RATE` on the bench's domain (with `--clock` when asked),
/// its stderr piped for [`played_said`].
fn play(bag: &Path, rate: f64, clock: bool) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args(["play", bag.to_str().unwrap(), "--reliable", "--wait-s", "30"])
        .args(clock.then_some("--clock"))
        .args(["--rate", &rate.to_string(), "--domain-id", &DOMAIN.to_string()])
        .stderr(Stdio::piped())
        .spawn()
        .expect("start fdavar play")
}

/// What a finished `fdavar play` said on stderr; panics unless it ended well.
fn played_said(player: &mut std::process::Child, status: std::process::ExitStatus) -> String {
    let mut said = String::new();
    std::io::Read::read_to_string(player.stderr.as_mut().unwrap(), &mut said).unwrap();
    // Exit 3: finished with warnings (here the bag's temperature topic, which it does not play).
    assert!(matches!(status.code(), Some(0 | 3)), "fdavar play: {said}");
    said
}

/// The IMU messages `fdavar play` says it published ("fdavar play: N IMU and …").
fn imu_sent(said: &str) -> u64 {
    said.lines()
        .find_map(|l| l.split_once(" IMU ")?.0.rsplit(' ').next()?.parse().ok())
        .unwrap_or_else(|| panic!("no IMU count in {said:?}"))
}

/// Writes `out`: the first `n` IMU messages of `bag`, unchanged.
fn copy_first(bag: &Path, out: &Path, n: usize) {
    let reader = fdavar::bag::BagReader::open(bag).expect("open bag");
    let topic = reader.imu_topic(None).expect("IMU topic").name.clone();
    let mut w = fdavar::bag::BagWriter::create(out).expect("create bag");
    for m in reader.messages(&topic, None).expect("messages").take(n) {
        if let Ok(fdavar::bag::BagMessage::Imu { log_time_ns, sample }) = m {
            w.write_imu(&topic, log_time_ns, &sample, "imu_link").unwrap();
        }
    }
    w.finish().unwrap();
}

/// A fault of the `hostile` mode written into one message ([`hostile_hourly_fault`]).
#[derive(Clone, Copy, PartialEq)]
enum Fault {
    /// gyro_x NaN.
    Nan,
    /// Every axis ±1e300.
    Huge,
    /// The message sent twice (a duplicated stamp).
    Doubled,
    /// A zero stamp.
    ZeroStamp,
}

impl Fault {
    /// How many times the message is sent.
    fn copies(self) -> usize {
        if self == Fault::Doubled { 2 } else { 1 }
    }
}

/// The hourly faults of the `hostile` mode, written into `sample`, message k of the run: from the
/// 10th minute of every hour 200 samples with gyro_x NaN, 10 with every axis ±1e300, 5 messages
/// sent twice, 3 with a zero stamp.
fn hostile_hourly_fault(k: u64, sample: &mut fdavar::signal::ImuSample) -> Option<Fault> {
    match k % (3600 * RATE_HZ) {
        60_000..60_200 => {
            sample.gyro[0] = f64::NAN;
            Some(Fault::Nan)
        }
        90_000..90_010 => {
            let v = if k.is_multiple_of(2) { 1e300 } else { -1e300 };
            sample.gyro = [v; 3];
            sample.accel = [v; 3];
            Some(Fault::Huge)
        }
        120_000..120_005 => Some(Fault::Doubled),
        150_000..150_003 => {
            sample.stamp_ns = 0;
            Some(Fault::ZeroStamp)
        }
        _ => None,
    }
}

/// The stamps' offset in the `hostile` mode at message k of `total`: 30 s back from 40 % of the
/// messages for the rest of the run (a driver restarted on an older clock: 50 backwards stamps,
/// then a re-anchor), 13 h forward from 70 % (more than the 2²⁰ periods of the longest gap laid
/// out: a re-anchor).
fn hostile_clock_offset_ns(k: u64, total: u64) -> i64 {
    let back = if k >= total * 2 / 5 { -30_000_000_000 } else { 0 };
    let forward = if k >= total * 7 / 10 { 13 * 3_600_000_000_000 } else { 0 };
    back + forward
}

/// Rewrites the recording `bag` into `out` with the faults of the `hostile` mode
/// ([`hostile_hourly_fault`], [`hostile_clock_offset_ns`]); returns what was written. Log times,
/// which pace the replay, are unchanged.
fn inject_faults(bag: &Path, out: &Path, total: u64) -> String {
    let reader = fdavar::bag::BagReader::open(bag).expect("open bag");
    let topic = reader.imu_topic(None).expect("IMU topic").name.clone();
    let mut w = fdavar::bag::BagWriter::create(out).expect("create bag");
    let (mut nan, mut huge, mut doubled, mut zero) = (0, 0, 0, 0);
    let messages = reader.messages(&topic, None).expect("messages");
    for (k, m) in (0_u64..).zip(messages) {
        let Ok(fdavar::bag::BagMessage::Imu { log_time_ns, mut sample }) = m else {
            continue;
        };
        sample.stamp_ns += hostile_clock_offset_ns(k, total);
        let fault = hostile_hourly_fault(k, &mut sample);
        match fault {
            Some(Fault::Nan) => nan += 1,
            Some(Fault::Huge) => huge += 1,
            Some(Fault::Doubled) => doubled += 1,
            Some(Fault::ZeroStamp) => zero += 1,
            None => {}
        }
        for _ in 0..fault.map_or(1, Fault::copies) {
            w.write_imu(&topic, log_time_ns, &sample, "imu_link").unwrap();
        }
    }
    w.finish().unwrap();
    format!(
        "{nan} NaN samples, {huge} ±1e300 samples, {doubled} messages sent twice, {zero} zero \
         stamps, the clock 30 s back at message {}, 13 h forward at message {}",
        total * 2 / 5,
        total * 7 / 10
    )
}

fn value<'a>(values: &'a [fdavar::msgs::diagnostic_msgs::KeyValue], key: &str) -> Option<&'a str> {
    values
        .iter()
        .find(|kv| kv.key == key)
        .map(|kv| kv.value.as_str())
}

/// `fdavar diagnose BAG --json --first N --axis AXIS`: the axis's JSON.
fn offline(bag: &Path, first: u64, axis: &str) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_fdavar"))
        .args([
            "diagnose",
            bag.to_str().unwrap(),
            "--json",
            "--first",
            &first.to_string(),
        ])
        .args(["--axis", axis])
        .output()
        .expect("run fdavar diagnose");
    // Exit 3 (warnings: a failing fit) still prints the answer.
    assert!(
        matches!(out.status.code(), Some(0 | 3)),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("UTF-8 JSON");
    let v: serde_json::Value =
        serde_json::from_str(&numbers_as_strings(&text)).expect("fdavar diagnose --json");
    v["axes"][0].clone()
}

/// JSON text with every number turned into a string holding its text, so that it is parsed by
/// `str::parse::<f64>` (correctly rounded) rather than by serde_json's default float parser,
/// which may miss the nearest f64 by one ulp (its `float_roundtrip` feature is off).
fn numbers_as_strings(json: &str) -> String {
    let mut out = String::with_capacity(json.len() + 64);
    let (mut in_string, mut escaped, mut in_number) = (false, false, false);
    for c in json.chars() {
        if in_number && !matches!(c, '0'..='9' | '-' | '+' | '.' | 'e' | 'E') {
            out.push('"');
            in_number = false;
        }
        if in_string {
            let was_escaped = escaped;
            escaped = !was_escaped && c == '\\';
            in_string = was_escaped || c != '"';
        } else if c == '"' {
            in_string = true;
        } else if !in_number && matches!(c, '0'..='9' | '-') {
            out.push('"');
            in_number = true;
        }
        out.push(c);
    }
    if in_number {
        out.push('"');
    }
    out
}

/// Where the node's `/diagnostics` status and the offline JSON differ (none when equal); f64
/// values are compared exactly.
fn compare(
    live: &[fdavar::msgs::diagnostic_msgs::KeyValue],
    offline: &serde_json::Value,
) -> Vec<String> {
    let mut differences = Vec::new();
    let number = |s: &str| s.parse::<f64>().ok();
    let live_fit = value(live, "fit_error").and_then(number);
    if live_fit != offline["fit_error"].as_str().and_then(number) {
        differences.push(format!(
            "fit_error {live_fit:?} vs {}",
            offline["fit_error"]
        ));
    }
    let ids = |v: &serde_json::Value| -> Vec<String> {
        v.as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|x| x.as_str().or(x["effect"].as_str()).map(str::to_string))
                    .collect()
            })
            .unwrap_or_default()
    };
    let split = |s: Option<&str>| -> Vec<String> {
        s.filter(|s| !s.is_empty())
            .map(|s| s.split(',').map(str::to_string).collect())
            .unwrap_or_default()
    };
    for (key, json) in [("model", "model"), ("suggestions", "suggestions")] {
        let (l, o) = (split(value(live, key)), ids(&offline[json]));
        if l != o {
            differences.push(format!("{key} {l:?} vs {o:?}"));
        }
    }
    // Coefficients: "effect.name [unit]" (not ".sigma") against coefficients.effect.name.
    let mut live_coefs = BTreeMap::new();
    for kv in live {
        if let Some((name, _unit)) = kv.key.split_once(" [") {
            if !name.ends_with(".sigma") {
                live_coefs.insert(name.to_string(), number(&kv.value));
            }
        }
    }
    let mut offline_coefs = BTreeMap::new();
    for (effect, params) in offline["coefficients"].as_object().into_iter().flatten() {
        for (name, v) in params.as_object().into_iter().flatten() {
            offline_coefs.insert(format!("{effect}.{name}"), v["value"].as_str().and_then(number));
        }
    }
    if live_coefs != offline_coefs {
        differences.push(format!("coefficients {live_coefs:?} vs {offline_coefs:?}"));
    }
    differences
}
