//! The ROS 2 plumbing of `fdavar_node`: context, node, parameters, subscriptions, the analysis thread,
//! publishers.
//!
//! Data flow: the receive loop (the thread that calls [`run`]) takes `imu` messages off DDS. The
//! [`Monitor`] (checks, counters, the F-DAVAR engine) sits behind one mutex. When the analysis is
//! free and nothing waits in the queue, the receive loop analyses the message itself; otherwise
//! (the analysis thread is building a publication) it `try_send`s it into a bounded queue that the
//! analysis thread drains, in order; a full queue drops the sample and counts it, so the
//! subscription never blocks and memory never grows. The analysis thread builds `/diagnostics`
//! and `~/<axis>/state` at `publish_rate_hz` under the lock and publishes them after it.
//! Parameter changes arrive from ros2-client's parameter services on a channel and apply between
//! two samples.
//!
//! The whole-run diagnosis runs on a thread of its own, without the lock: at a publication the
//! monitor lends it the engine's whole-run record ([`Monitor::start_diagnosis`]); samples keep
//! coming into the rows meanwhile, those the record misses wait in the engine (bounded:
//! [`super::engine::DEFERRED_CAP`]; at the cap the input waits in the queue, which drops and
//! counts when full) and go into the record, in order, when the diagnosis gives it back
//! ([`Monitor::finish_diagnosis`], under the lock: about a millisecond). Why: samples that
//! arrived during a diagnosis used to wait behind it, which made the p99 receive-to-update
//! latency the diagnosis's cost (119 ms at 2 kHz, docs/ros.md has the measurements).
//!
//! Why the receive loop analyses when it can: handing every message to the analysis thread woke
//! a second thread per message (a futex wake and a context switch on each side); the F-DAVAR
//! update of six axes costs less than that hand-off. The queue stays for the times the analysis
//! is busy (docs/ros.md; "Node at 2 kHz" in docs/performance.md has the measured gain).

use super::args::RosArgs;
use super::dump::DumpWriter;
use super::monitor::{Change, DiagnosisJob, Monitor, MonitorSettings, RowEngine};
use super::names::{check_node_name, normalise_namespace, resolve, NameError};
use super::params::{self, ParamError, NODE_PARAMS};
use crate::msgs::diagnostic_msgs::{DiagnosticArray, KeyValue};
use crate::msgs::fdavar_msgs::AxisState;
use crate::msgs::rosgraph_msgs::Clock;
use crate::msgs::sensor_msgs::{Imu, Temperature};
use crate::msgs::RosMessage;
use crate::signal::ImuSample;
use futures::Stream;
use ros2_client::qos::{History, Reliability, WhenFull};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, ParameterValue,
    Publisher, QosProfile, Subscription,
};
use std::collections::BTreeMap;
use std::pin::Pin;
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender, SyncSender, TrySendError};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, TryLockError};
use std::task::{Context as TaskContext, Poll as TaskPoll};
use std::time::{Duration, Instant};

/// Why the node could not start (a startup configuration error: exit non-zero).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NodeError {
    /// `--ros-args` was malformed.
    #[error(transparent)]
    Args(#[from] super::args::ArgsError),
    /// A node, namespace or topic name is invalid.
    #[error(transparent)]
    Name(#[from] NameError),
    /// A parameter value was refused.
    #[error(transparent)]
    Param(#[from] ParamError),
    /// `ROS_DOMAIN_ID` is not a number in 0..=232.
    #[error("ROS_DOMAIN_ID='{0}' is not a domain id (0..=232)")]
    DomainId(String),
    /// ros2-client / DDS refused to create an entity.
    #[error("ROS 2 ({what}): {reason}")]
    Ros {
        /// What was being created.
        what: String,
        /// The client's error.
        reason: String,
    },
    /// The dump file could not be opened.
    #[error("dump_json {path}: {source}")]
    Dump {
        /// The path.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
}

fn ros_err(what: impl Into<String>) -> impl FnOnce(String) -> NodeError {
    let what = what.into();
    move |reason| NodeError::Ros { what, reason }
}

/// Everything the node needs to start, read from `--ros-args` and the environment.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeConfig {
    /// Absolute namespace (`/` for the root).
    pub namespace: String,
    /// Node base name (`fdavar` unless `__node:=` says otherwise).
    pub name: String,
    /// Remaps from `-r from:=to`.
    pub remaps: Vec<(String, String)>,
    /// The node's own parameter values (defaults, files, `-p`), validated.
    pub params: BTreeMap<String, ParameterValue>,
    /// The DAVAR parameter values (same table as `fdavar davar --params`), validated.
    pub davar: BTreeMap<String, crate::params::ParamValue>,
    /// The DAVAR configuration they make.
    pub davar_config: crate::pipeline::DavarConfig,
    /// DDS domain (`ROS_DOMAIN_ID`, default 0).
    pub domain_id: u16,
    /// `--log-level`: `debug`, `info` (default), `warn`, `error`, `fatal`.
    pub log_level: String,
}

impl NodeConfig {
    /// Reads the configuration from `--ros-args` (program arguments are returned, untouched) and
    /// `ROS_DOMAIN_ID` (given here so that tests need not set the environment).
    ///
    /// # Errors
    /// [`NodeError`] for malformed arguments, invalid names or parameter values, a bad domain id.
    pub fn from_args<I, S>(
        args: I,
        ros_domain_id: Option<&str>,
    ) -> Result<(NodeConfig, Vec<String>), NodeError>
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        let (ros, rest) = RosArgs::parse(args)?;
        let namespace = normalise_namespace(ros.namespace.as_deref().unwrap_or("/"))?;
        let name = ros
            .node_name
            .clone()
            .unwrap_or_else(|| "fdavar".to_string());
        check_node_name(&name)?;
        let fqn = if namespace == "/" {
            format!("/{name}")
        } else {
            format!("{namespace}/{name}")
        };
        let params = params::startup_values(&ros.params_files, &ros.params, &fqn)?;
        let (davar, davar_config) = params::davar_startup(&ros.params_files, &ros.params)?;
        let domain_id = match ros_domain_id.map(str::trim).filter(|s| !s.is_empty()) {
            None => 0,
            Some(s) => s
                .parse::<u16>()
                .ok()
                .filter(|d| *d <= 232)
                .ok_or_else(|| NodeError::DomainId(s.to_string()))?,
        };
        let config = NodeConfig {
            namespace,
            name,
            remaps: ros.remaps,
            params,
            davar,
            davar_config,
            domain_id,
            log_level: ros.log_level.unwrap_or_else(|| "info".to_string()),
        };
        // Resolve every name now, so that a bad remap is a startup error.
        for topic in [
            "imu",
            "temperature",
            "/clock",
            "/diagnostics",
            "~/gyro_x/state",
        ] {
            config.resolve(topic)?;
        }
        Ok((config, rest))
    }

    /// A topic name resolved by ROS rules (namespace, `~`, remaps); always absolute.
    ///
    /// # Errors
    /// [`NameError`] for an invalid name or remap target.
    pub fn resolve(&self, name: &str) -> Result<String, NameError> {
        resolve(name, &self.namespace, &self.name, &self.remaps)
    }

    fn double(&self, name: &str) -> f64 {
        match self.params.get(name) {
            Some(ParameterValue::Double(x)) => *x,
            _ => f64::NAN,
        }
    }

    /// The integer parameter `name` (0 when it is not one; validated parameters always are).
    pub(crate) fn int(&self, name: &str) -> i64 {
        match self.params.get(name) {
            Some(ParameterValue::Integer(i)) => *i,
            _ => 0,
        }
    }

    fn flag(&self, name: &str) -> bool {
        matches!(self.params.get(name), Some(ParameterValue::Boolean(true)))
    }

    /// The string parameter `name` (empty when it is not one; validated parameters always are).
    pub(crate) fn text(&self, name: &str) -> String {
        match self.params.get(name) {
            Some(ParameterValue::String(s)) => s.clone(),
            _ => String::new(),
        }
    }
}

/// A validated live parameter change, from the parameter services to the analysis thread.
enum Control {
    /// One of the node's own parameters.
    Node(String, ParameterValue),
    /// A DAVAR parameter: the whole new configuration.
    Davar(String, Box<crate::pipeline::DavarConfig>),
}

/// What flows from the receive loop to the analysis thread.
enum Input {
    Imu {
        sample: ImuSample,
        frame_id: String,
        receive_ns: i64,
        /// When DDS received it, wall-clock ns since the Unix epoch (RustDDS stamps each sample
        /// as its participant thread takes it off the socket): the receive-to-update latency
        /// counts from there, the wait for the receive loop's wake-up included.
        arrived_ns: i64,
    },
    Temperature(crate::signal::TemperatureSample),
}

/// Receive-to-update latencies of the most recent samples (a bounded ring).
///
/// Why in the node: whether the analysis keeps up with the IMU is a property of the running
/// system; `/diagnostics` shows its median and 99th percentile.
struct Latency {
    ring: Vec<f64>,
    next: usize,
}

impl Latency {
    const CAPACITY: usize = 8192;

    fn record(&mut self, seconds: f64) {
        if self.ring.len() < Self::CAPACITY {
            self.ring.push(seconds);
        } else {
            self.ring[self.next] = seconds;
        }
        self.next = (self.next + 1) % Self::CAPACITY;
    }

}

/// (p50, p99) in milliseconds of the latencies `ring` (a copy of [`Latency`]'s: it is reordered),
/// if any.
fn percentiles_ms(ring: &mut [f64]) -> Option<(f64, f64)> {
    if ring.is_empty() {
        return None;
    }
    let last = ring.len() - 1;
    let mut at = |q: f64| {
        let k = (last as f64 * q).round() as usize;
        *ring.select_nth_unstable_by(k, f64::total_cmp).1 * 1e3
    };
    Some((at(0.5), at(0.99)))
}

/// A logger honouring `--log-level`, writing ROS-style lines to stderr.
#[derive(Debug, Clone)]
struct Log {
    name: String,
    quiet_info: bool,
}

impl Log {
    fn info(&self, msg: &str) {
        if !self.quiet_info {
            eprintln!("[INFO] [{}]: {msg}", self.name);
        }
    }
    fn warn(&self, msg: &str) {
        eprintln!("[WARN] [{}]: {msg}", self.name);
    }
}

/// The node's clock: wall time, or the last `/clock` message when `use_sim_time` is true.
#[derive(Debug, Clone)]
struct NodeClock {
    sim: Option<Arc<AtomicI64>>,
}

impl NodeClock {
    fn now_ns(&self) -> i64 {
        match &self.sim {
            Some(t) => t.load(Ordering::Relaxed),
            None => wall_ns(),
        }
    }
}

fn topic_type<M: RosMessage>() -> MessageTypeName {
    MessageTypeName::new(M::DEF.package(), M::DEF.type_name())
}

fn status_qos(depth: usize) -> QosProfile {
    QosProfile::publisher_default().history(History::KeepLast { depth })
}

/// Runs the node until `stop` becomes true (`fdavar_node` sets it on SIGINT/SIGTERM), then
/// analyses the samples already queued, flushes `dump_json` and returns.
///
/// `engine` is the F-DAVAR engine the analysis thread drives (`None`: input checks and counters
/// only).
///
/// # Errors
/// [`NodeError`] when a ROS entity cannot be created (startup); once running, bad input is logged
/// and counted, never returned.
pub fn run(
    config: &NodeConfig,
    engine: Option<Box<dyn RowEngine>>,
    stop: Arc<AtomicBool>,
) -> Result<(), NodeError> {
    let log = Log {
        name: config.name.clone(),
        quiet_info: matches!(config.log_level.as_str(), "warn" | "error" | "fatal"),
    };
    let context = Context::with_options(ContextOptions::new().domain_id(config.domain_id))
        .map_err(|e| ros_err("context")(format!("{e:?}")))?;

    // Parameter changes travel from the spinner's set action to the analysis thread.
    let (param_tx, param_rx) = mpsc::channel::<Control>();
    let param_tx = std::sync::Mutex::new(param_tx);
    // The DAVAR values in force: a change is validated together with the others.
    let davar_now = Arc::new(std::sync::Mutex::new(config.davar.clone()));
    let davar_check = Arc::clone(&davar_now);
    // The stamps' period once the analysis has seen it (f64 bits; 0 = not yet): a live tau0 is
    // checked against it.
    let period_bits = Arc::new(AtomicU64::new(0));
    let (period_check, period_set) = (Arc::clone(&period_bits), Arc::clone(&period_bits));
    // ros2-client also runs the validator and the set action on the declared (startup) values,
    // which were checked when read (defaults are trusted): until the node exists, both accept.
    let running = Arc::new(AtomicBool::new(false));
    let (validating, setting) = (Arc::clone(&running), Arc::clone(&running));
    let mut options = NodeOptions::new()
        .enable_rosout(true)
        .start_parameter_services(true)
        .parameter_validator(Box::new(move |name, value| {
            if !validating.load(Ordering::Acquire) {
                return Ok(());
            }
            if params::is_davar(name) {
                let current = davar_check
                    .lock()
                    .map_err(|_| "parameter lock poisoned".to_string())?;
                let measured = measured_period(&period_check);
                return params::davar_change_live(&current, name, value, measured).map(|_| ());
            }
            let spec = params::spec(name).ok_or_else(|| format!("unknown parameter '{name}'"))?;
            if !spec.live {
                return Err(format!(
                    "'{name}' is read at startup only; restart the node to change it"
                ));
            }
            params::validate(name, value)
                .map(|_| ())
                .map_err(|e| e.to_string())
        }))
        .parameter_set_action(Box::new(move |name, value| {
            if !setting.load(Ordering::Acquire) {
                return Ok(());
            }
            let control = if params::is_davar(name) {
                let mut current = davar_now
                    .lock()
                    .map_err(|_| "parameter lock poisoned".to_string())?;
                let measured = measured_period(&period_set);
                let (next, config) = params::davar_change_live(&current, name, value, measured)?;
                *current = next;
                Control::Davar(name.to_string(), Box::new(config))
            } else {
                let value = params::validate(name, value).map_err(|e| e.to_string())?;
                Control::Node(name.to_string(), value)
            };
            param_tx
                .lock()
                .map_err(|_| "parameter channel poisoned".to_string())?
                .send(control)
                .map_err(|_| "analysis thread stopped".to_string())
        }));
    for spec in NODE_PARAMS {
        let value = config
            .params
            .get(spec.name)
            .cloned()
            .unwrap_or_else(spec.default);
        options = options.declare_parameter(spec.name, value);
    }
    for (name, value) in &config.davar {
        options = options.declare_parameter(name, params::ros_value(value));
    }
    let mut node = context
        .new_node(
            NodeName::new(&config.namespace, &config.name)
                .map_err(|e| ros_err("node name")(format!("{e:?}")))?,
            options,
        )
        .map_err(|e| ros_err("node")(format!("{e:?}")))?;
    running.store(true, Ordering::Release);

    let depth = usize::try_from(config.int("qos.depth")).unwrap_or(100);
    let imu_qos = if config.flag("qos.reliable") {
        QosProfile::subscription_default()
            .reliability_reliable(WhenFull::DEFAULT)
            .history(History::KeepLast { depth })
    } else {
        QosProfile::subscription_default()
            .reliability(Reliability::BestEffort)
            .history(History::KeepLast { depth })
    };
    let imu_name = config.resolve("imu")?;
    let imu_sub: Subscription<Imu> =
        subscribe(&mut node, &imu_name, topic_type::<Imu>(), &imu_qos)?;
    let temp_sub: Option<Subscription<Temperature>> = if config.flag("temperature") {
        let name = config.resolve("temperature")?;
        Some(subscribe(
            &mut node,
            &name,
            topic_type::<Temperature>(),
            &imu_qos,
        )?)
    } else {
        None
    };
    let sim_time = config
        .flag("use_sim_time")
        .then(|| Arc::new(AtomicI64::new(0)));
    let clock_sub: Option<Subscription<Clock>> = match &sim_time {
        Some(_) => {
            let qos = QosProfile::subscription_default().history(History::KeepLast { depth: 1 });
            Some(subscribe(
                &mut node,
                &config.resolve("/clock")?,
                topic_type::<Clock>(),
                &qos,
            )?)
        }
        None => None,
    };
    let clock = NodeClock {
        sim: sim_time.clone(),
    };

    let diag_pub: Publisher<DiagnosticArray> = publish(
        &mut node,
        &config.resolve("/diagnostics")?,
        topic_type::<DiagnosticArray>(),
        &status_qos(10),
    )?;
    let mut state_pubs = Vec::new();
    for axis in crate::signal::Axis::ALL {
        let name = config.resolve(&format!("~/{axis}/state"))?;
        state_pubs.push(publish::<AxisState>(
            &mut node,
            &name,
            topic_type::<AxisState>(),
            &status_qos(10),
        )?);
    }

    let dump_path = config.text("dump_json");
    let dump = if dump_path.is_empty() {
        None
    } else {
        // The validator bounds the cap to [1, 10⁶] MB, so the product is a whole number of bytes.
        let max_bytes = (config.double("dump_json_max_mb") * 1e6) as u64;
        Some(
            DumpWriter::create(
                std::path::Path::new(&dump_path),
                max_bytes,
                config.double("dump_every_s"),
            )
            .map_err(|source| NodeError::Dump {
                path: dump_path.clone(),
                source,
            })?,
        )
    };

    let spinner = node
        .spinner()
        .map_err(|e| ros_err("spinner")(format!("{e:?}")))?;
    std::thread::Builder::new()
        .name("fdavar-spin".into())
        .spawn(move || futures::executor::block_on(spinner.spin()))
        .map_err(|e| ros_err("spinner thread")(e.to_string()))?;

    let publishers = Publishers {
        diagnostics: diag_pub,
        states: state_pubs,
        log: log.clone(),
    };
    let queue_size = usize::try_from(config.int("queue_size")).unwrap_or(1);
    let (tx, rx) = mpsc::sync_channel::<Input>(queue_size);
    let drops = Arc::new(AtomicU64::new(0));
    let settings = MonitorSettings {
        stale_timeout_s: config.double("stale_timeout_s"),
        diagnosis_period_s: config.double("diagnosis_period_s"),
        diagnosis_cpu_share: config.double("diagnosis_cpu_share"),
        ..MonitorSettings::default()
    };
    let mut monitor = Monitor::new(settings, engine);
    if dump.is_some() {
        monitor.record_rows();
    }
    let analysis = Analysis {
        monitor,
        settings,
        publish_period: Duration::from_secs_f64(1.0 / config.double("publish_rate_hz")),
        clock: clock.clone(),
        log: log.clone(),
        drops: Arc::clone(&drops),
        period_bits,
        dump,
        latency: Latency {
            ring: Vec::new(),
            next: 0,
        },
        params: param_rx,
    };
    let shared = Arc::new(Shared {
        analysis: Mutex::new(analysis),
        queued: AtomicUsize::new(0),
        given_back: Condvar::new(),
    });
    let (jobs_tx, jobs_rx) = mpsc::channel::<DiagnosisJob>();
    {
        // Not joined: a diagnosis still running at shutdown has nothing left to publish to.
        let shared = Arc::clone(&shared);
        std::thread::Builder::new()
            .name("fdavar-diagnose".into())
            .spawn(move || diagnosis_loop(&shared, &jobs_rx))
            .map_err(|e| ros_err("diagnosis thread")(e.to_string()))?;
    }
    let analysis_thread = {
        let shared = Arc::clone(&shared);
        std::thread::Builder::new()
            .name("fdavar-analysis".into())
            .spawn(move || analysis_loop(&shared, &rx, &publishers, &jobs_tx))
            .map_err(|e| ros_err("analysis thread")(e.to_string()))?
    };
    log.info(&format!(
        "fdavar_node {} on domain {}: imu '{imu_name}' ({}, depth {depth}), queue {queue_size}",
        node.fully_qualified_name(),
        config.domain_id,
        if config.flag("qos.reliable") {
            "reliable"
        } else {
            "best effort"
        },
    ));

    let batching = Batching {
        period: Duration::from_secs_f64(config.double("receive_batch_ms") * 1e-3),
        // A quarter of the reader's history: a batch that large means messages come faster
        // than the period allows, and waiting the period out could overflow the history.
        full: depth.div_ceil(4),
    };
    receive_loop(
        &imu_sub,
        &batching,
        temp_sub.as_ref(),
        clock_sub.as_ref(),
        sim_time.as_deref(),
        &clock,
        &shared,
        &tx,
        &drops,
        &stop,
        &log,
    );
    if stop.load(Ordering::Relaxed) {
        log.info("stopping: analysing the queued samples and flushing outputs");
    }
    // Closing the queue ends the analysis thread once it has drained it.
    drop(tx);
    if analysis_thread.join().is_err() {
        log.warn("the analysis thread panicked; outputs may be incomplete");
    }
    node.stop_spinner();
    Ok(())
}

/// A DDS topic for an absolute ROS name (never relative: see [`super::names`]).
fn topic(
    node: &mut Node,
    name: &str,
    type_name: MessageTypeName,
    qos: &QosProfile,
) -> Result<ros2_client::dds::rustdds::Topic, NodeError> {
    let ros_name =
        Name::parse(name).map_err(|e| ros_err(format!("topic {name}"))(format!("{e:?}")))?;
    node.create_topic(&ros_name, type_name, qos)
        .map_err(|e| ros_err(format!("topic {name}"))(format!("{e:?}")))
}

fn subscribe<M: 'static + serde::de::DeserializeOwned>(
    node: &mut Node,
    name: &str,
    type_name: MessageTypeName,
    qos: &QosProfile,
) -> Result<Subscription<M>, NodeError> {
    let topic = topic(node, name, type_name, qos)?;
    node.create_subscription(&topic, Some(qos.clone()))
        .map_err(|e| ros_err(format!("subscription {name}"))(format!("{e:?}")))
}

/// A subscription to `M` on the absolute topic `name` (used by the node benchmark).
///
/// # Errors
/// [`NodeError::Ros`] when the name is invalid or DDS refuses.
pub fn subscribe_on<M: RosMessage + 'static>(
    node: &mut Node,
    name: &str,
    qos: &QosProfile,
) -> Result<Subscription<M>, NodeError> {
    subscribe(node, name, topic_type::<M>(), qos)
}

/// A publisher of `M` on the absolute topic `name` (used by `fdavar play` too).
///
/// # Errors
/// [`NodeError::Ros`] when the name is invalid or DDS refuses.
pub fn publish_on<M: RosMessage>(
    node: &mut Node,
    name: &str,
    qos: &QosProfile,
) -> Result<Publisher<M>, NodeError> {
    publish(node, name, topic_type::<M>(), qos)
}

/// A ROS 2 node of its own on `domain_id`, without `/rosout`: how `fdavar play`, the node
/// benchmarks and the interop tests talk to `fdavar_node` from a Rust process (the node keeps its
/// DDS context alive). Make its topics, then [`spin_in_background`].
///
/// # Errors
/// [`NodeError::Ros`] when the name is invalid or DDS refuses.
pub fn peer_node(domain_id: u16, name: &str) -> Result<Node, NodeError> {
    let context = Context::with_options(ContextOptions::new().domain_id(domain_id))
        .map_err(|e| ros_err("context")(format!("{e:?}")))?;
    let name = NodeName::new("/", name).map_err(|e| ros_err("node name")(format!("{e:?}")))?;
    context
        .new_node(name, NodeOptions::new().enable_rosout(false))
        .map_err(|e| ros_err("node")(format!("{e:?}")))
}

/// Runs `node`'s spinner on a thread of its own: discovery runs there, so a publisher's match
/// count stays 0 until it does.
///
/// # Errors
/// [`NodeError::Ros`] when the node already has a spinner.
pub fn spin_in_background(node: &mut Node) -> Result<(), NodeError> {
    let spinner = node.spinner().map_err(|e| ros_err("spinner")(format!("{e:?}")))?;
    std::thread::spawn(move || futures::executor::block_on(spinner.spin()));
    Ok(())
}

/// Waits, polling every 50 ms, until `publisher` has at least `count` subscribers; false once
/// `timeout` passed with fewer. The node must spin ([`spin_in_background`]).
pub fn wait_for_subscribers<M: serde::Serialize>(
    publisher: &Publisher<M>,
    node: &Node,
    count: usize,
    timeout: Duration,
) -> bool {
    let by = Instant::now() + timeout;
    while publisher.get_subscription_count(node) < count {
        if Instant::now() >= by {
            return false;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    true
}

fn publish<M: serde::Serialize>(
    node: &mut Node,
    name: &str,
    type_name: MessageTypeName,
    qos: &QosProfile,
) -> Result<Publisher<M>, NodeError> {
    let topic = topic(node, name, type_name, qos)?;
    node.create_publisher(&topic, Some(qos.clone()))
        .map_err(|e| ros_err(format!("publisher {name}"))(format!("{e:?}")))
}

/// Wakes the receive loop's thread (parked between messages) when DDS has data.
struct Unpark(std::thread::Thread);

impl std::task::Wake for Unpark {
    fn wake(self: Arc<Self>) {
        self.0.unpark();
    }
    fn wake_by_ref(self: &Arc<Self>) {
        self.0.unpark();
    }
}

/// Takes every message `stream` has ready, handing each to `each` (false from it: stop);
/// returns false when `each` did, and leaves the stream's waker set for the next message.
fn take_ready<M>(
    mut stream: Pin<
        &mut impl Stream<Item = ros2_client::ReadResult<(M, ros2_client::MessageInfo)>>,
    >,
    cx: &mut TaskContext<'_>,
    mut each: impl FnMut(ros2_client::ReadResult<(M, ros2_client::MessageInfo)>) -> bool,
) -> bool {
    while let TaskPoll::Ready(Some(read)) = stream.as_mut().poll_next(cx) {
        if !each(read) {
            return false;
        }
    }
    true
}

/// How the receive loop waits for IMU messages that come faster than one per `period`
/// (`receive_batch_ms`).
struct Batching {
    /// How long the first message of a batch waits for its take while messages come that fast;
    /// zero: woken by DDS for each.
    period: Duration,
    /// A take of this many messages or more is followed at once by the next.
    full: usize,
}

impl Batching {
    /// The wait before the next take, at `now_ns`, when the latest message arrived at
    /// `last_arrival_ns` (RustDDS's reception stamps, wall clock), `gap_ns` after the one before.
    ///
    /// The take is timed for the k messages due next, one gap apart, to have all arrived, a
    /// quarter of a gap after the k-th is due (a message that late still makes its batch), with
    /// k the most for which the first has waited no longer than `period` by then.
    ///
    /// Why from the arrivals rather than `period` after each take: a take at a fixed time after
    /// the last found 1.7 messages on average at 2 kHz with 0.8 ms (1 170 wake-ups a second,
    /// each a context switch), and a message could wait the whole period and the sleep's lateness
    /// after it; timed just after the k-th arrival, each take finds k = 2 and the first has
    /// waited one gap and a quarter (0.63 ms). A stamp that is not where the clock says (a step
    /// of the wall clock) waits at most the k gaps and the quarter.
    fn wait(&self, last_arrival_ns: i64, gap_ns: i64, now_ns: i64) -> Duration {
        let (period_ns, gap_ns) = (self.period.as_nanos() as i64, gap_ns.max(1));
        let late_ns = gap_ns / 4;
        let k = 1 + (period_ns - late_ns).max(0) / gap_ns;
        let ahead_ns = k.saturating_mul(gap_ns).saturating_add(late_ns);
        let due_ns = last_arrival_ns.saturating_add(ahead_ns);
        Duration::from_nanos(due_ns.saturating_sub(now_ns).clamp(0, ahead_ns) as u64)
    }
}

/// Takes messages off DDS and analyses or queues them ([`Shared::hand_over`]); never blocks on the
/// analysis.
///
/// Why batches on a timer while messages come faster than one per period ([`Batching`]): DDS's
/// wake-up of this thread for each message, and this thread's sleep after it, were most of the
/// node's CPU at 2 kHz (docs/performance.md, "Node at 2 kHz"). While batching, the IMU stream is polled with a
/// no-op waker, so that DDS wakes nobody; a take that finds nothing polls once more with the
/// thread's own waker and parks until DDS wakes it. Slower topics (the last two messages
/// further apart than a period, by RustDDS's reception stamps) are taken as DDS wakes the thread
/// for each: a timed take after each of them would find nothing and double the wake-ups.
///
/// Why the subscriptions' async streams, polled by hand on this thread, rather than a mio `Poll`
/// (as before): a stream leaves a waker that DDS calls once per message (one thread unpark),
/// where the mio source is a socket pair that cost an `epoll_wait` and two or three `recv` calls
/// per message (each `Subscription::take` drains it): up to a fifth of the node's samples in a
/// `perf record` at 2 kHz (docs/performance.md, node rows, has the measured gain). Nobody reads the socket
/// pair now: once full, DDS's writes to it fail at once.
#[allow(clippy::too_many_arguments)]
fn receive_loop(
    imu: &Subscription<Imu>,
    batching: &Batching,
    temperature: Option<&Subscription<Temperature>>,
    clock_sub: Option<&Subscription<Clock>>,
    sim_time: Option<&AtomicI64>,
    clock: &NodeClock,
    shared: &Shared,
    tx: &SyncSender<Input>,
    drops: &AtomicU64,
    stop: &AtomicBool,
    log: &Log,
) {
    precise_sleeps();
    let waker = std::task::Waker::from(Arc::new(Unpark(std::thread::current())));
    let mut cx = TaskContext::from_waker(&waker);
    let mut imu_stream = std::pin::pin!(imu.async_stream());
    let mut temperature_stream = std::pin::pin!(temperature.map(Subscription::async_stream));
    let mut clock_stream = std::pin::pin!(clock_sub.map(Subscription::async_stream));
    let mut read_errors_logged = false;
    let mut batch_cx = TaskContext::from_waker(std::task::Waker::noop());
    let mut batching_now = false;
    let period_ns = batching.period.as_nanos() as i64;
    // RustDDS's reception stamp of the latest IMU message, and its distance from the one before.
    let (mut last_arrival_ns, mut last_gap_ns) = (None::<i64>, i64::MAX);
    while !stop.load(Ordering::Relaxed) {
        if let (Some(s), Some(t)) = (clock_stream.as_mut().as_pin_mut(), sim_time) {
            take_ready(s, &mut cx, |read| {
                if let Ok((msg, _)) = read {
                    t.store(msg.clock.to_ns(), Ordering::Relaxed);
                }
                true
            });
        }
        let mut taken = 0_usize;
        let imu_cx = if batching_now { &mut batch_cx } else { &mut cx };
        let open = take_ready(imu_stream.as_mut(), imu_cx, |read| match read {
            Ok((msg, info)) => {
                taken += 1;
                let arrived_ns = info.received_timestamp().map_or_else(wall_ns, |t| t.to_nanos());
                last_gap_ns = last_arrival_ns.map_or(i64::MAX, |t| arrived_ns.saturating_sub(t));
                last_arrival_ns = Some(arrived_ns);
                let input = Input::Imu {
                    // A zero stamp stays zero here: the monitor decides (by the stream's
                    // clock) what it means.
                    sample: msg.to_sample(0),
                    frame_id: msg.header.frame_id,
                    receive_ns: clock.now_ns(),
                    arrived_ns,
                };
                match shared.hand_over(input, tx) {
                    HandOver::Done => true,
                    HandOver::Full => {
                        drops.fetch_add(1, Ordering::Relaxed);
                        true
                    }
                    HandOver::Closed => false,
                }
            }
            Err(e) => {
                // An undecodable message: count nothing we cannot attribute, log once.
                if !read_errors_logged {
                    log.warn(&format!(
                        "an IMU message could not be read ({e:?}); such messages are skipped"
                    ));
                    read_errors_logged = true;
                }
                true
            }
        });
        if !open {
            return;
        }
        if let Some(s) = temperature_stream.as_mut().as_pin_mut() {
            let open = take_ready(s, &mut cx, |read| {
                let Ok((msg, _)) = read else { return true };
                let reading = crate::signal::TemperatureSample {
                    stamp_ns: msg.header.stamp.to_ns(),
                    celsius: msg.temperature,
                };
                // A full queue drops the reading: a slow topic, one reading less in a block mean.
                !matches!(
                    shared.hand_over(Input::Temperature(reading), tx),
                    HandOver::Closed
                )
            });
            if !open {
                return;
            }
        }
        // (A negative gap is the wall clock stepping back: no evidence of a fast topic.)
        if let Some(last_ns) = last_arrival_ns.filter(|_| taken > 0 && (0..period_ns).contains(&last_gap_ns)) {
            batching_now = true;
            if taken < batching.full {
                std::thread::sleep(batching.wait(last_ns, last_gap_ns, wall_ns()));
            }
            continue;
        }
        if batching_now {
            // Nothing came during the wait, or the topic slowed below one message per period:
            // take once more with the waker set, then park until DDS wakes the thread.
            batching_now = false;
            continue;
        }
        // Until the next message of any subscription (whose wake may have come already: then
        // this returns at once), or in time to see `stop`.
        std::thread::park_timeout(Duration::from_millis(100));
    }
}

/// The stamps' period the analysis thread stored, once known.
fn measured_period(bits: &AtomicU64) -> Option<f64> {
    Some(f64::from_bits(bits.load(Ordering::Relaxed))).filter(|p| *p > 0.0)
}

/// Wall-clock time, ns since the Unix epoch (the clock RustDDS stamps received samples with).
fn wall_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i64)
}

/// What [`Shared::hand_over`] did with an input.
enum HandOver {
    /// Analysed, or queued for the analysis thread.
    Done,
    /// The queue was full: the input is dropped.
    Full,
    /// The analysis thread has stopped.
    Closed,
}

/// The analysis and the count of inputs queued for it but not analysed yet.
struct Shared {
    analysis: Mutex<Analysis>,
    /// Notified when a diagnosis has given back what it was lent (the engine takes inputs again).
    given_back: Condvar,
    /// Inputs sent into the queue and not yet analysed. Only the receive loop increments it, and
    /// the analysis thread decrements it under the lock once an input is analysed: so when the
    /// receive loop holds the lock and reads 0, no earlier input is still waiting, and analysing
    /// the new one at once keeps the order.
    queued: AtomicUsize,
}

impl Shared {
    /// The analysis, waiting for the lock. A panic while it was held cannot leave the monitor
    /// half-updated in a way that matters more than stopping would: the engine's own panics are
    /// caught inside the monitor (reported as ERROR), so the state is used as it is.
    fn lock(&self) -> MutexGuard<'_, Analysis> {
        self.analysis
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// The analysis if it is free now, takes an input, and nothing waits in the queue before
    /// the new input.
    fn free(&self) -> Option<MutexGuard<'_, Analysis>> {
        if self.queued.load(Ordering::SeqCst) != 0 {
            return None;
        }
        let guard = match self.analysis.try_lock() {
            Ok(g) => g,
            Err(TryLockError::Poisoned(p)) => p.into_inner(),
            Err(TryLockError::WouldBlock) => return None,
        };
        (self.queued.load(Ordering::SeqCst) == 0 && guard.monitor.can_take()).then_some(guard)
    }

    /// `analysis` once its engine takes inputs again (at once unless a lent diagnosis holds as
    /// many as it may), the lock released meanwhile.
    fn when_taking<'a>(&self, analysis: MutexGuard<'a, Analysis>) -> MutexGuard<'a, Analysis> {
        self.given_back
            .wait_while(analysis, |a| !a.monitor.can_take())
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Analyses `input` on the calling thread (the receive loop) when the analysis is free,
    /// queues it for the analysis thread otherwise.
    fn hand_over(&self, input: Input, tx: &SyncSender<Input>) -> HandOver {
        if let Some(mut analysis) = self.free() {
            analysis.take(input);
            return HandOver::Done;
        }
        self.queued.fetch_add(1, Ordering::SeqCst);
        match tx.try_send(input) {
            Ok(()) => HandOver::Done,
            Err(e) => {
                self.queued.fetch_sub(1, Ordering::SeqCst);
                match e {
                    TrySendError::Full(_) => HandOver::Full,
                    TrySendError::Disconnected(_) => HandOver::Closed,
                }
            }
        }
    }
}

/// Runs the diagnoses the analysis thread starts, and hands each back under the lock.
fn diagnosis_loop(shared: &Shared, jobs: &Receiver<DiagnosisJob>) {
    background_priority();
    while let Ok(job) = jobs.recv() {
        let done = job.run();
        shared.lock().monitor.finish_diagnosis(done);
        shared.given_back.notify_all();
        crate::analysis::give_back_free_heap_pages();
    }
}

/// Lowers the calling thread's priority to nice 10 (Linux: a thread's own).
///
/// Why for the diagnosis thread: on a busy machine it competes with the receive thread for a
/// core, and at equal priority a sample can wait a scheduler slice (milliseconds) behind a
/// diagnosis. At nice 10 the receive thread wins the core; the diagnosis still gets about a
/// tenth of a contended core, and all of an idle one.
fn background_priority() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: setpriority only changes the scheduling weight of the calling thread (gettid);
    // a refusal leaves it as it was.
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, libc::gettid() as libc::id_t, 10);
    }
}

/// Lets the calling thread's sleeps end on time: a timer slack of 1 ns instead of Linux's 50 µs
/// default (`PR_SET_TIMERSLACK`).
///
/// Why for the receive thread: its batch sleep is timed for the next messages to have arrived
/// ([`Batching::wait`]), and the kernel may end a sleep up to the slack late, with every message of
/// the batch waiting. Measured at 2 kHz (`cargo bench --bench node_load -- 2000 40 10 0 0.005 0.8
/// bare`, four runs each, interleaved): p99 receive-to-update 0.88–0.96 ms against 0.96–1.05 ms.
fn precise_sleeps() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: PR_SET_TIMERSLACK changes only the calling thread's timer slack; a refusal leaves
    // it as it was.
    unsafe {
        libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong);
    }
}

/// The analysis thread: analyses what the receive loop queued (in order), applies parameter
/// changes, publishes at `publish_rate_hz` and starts the diagnoses then (on `jobs`); ends once
/// the queue is closed and drained.
fn analysis_loop(
    shared: &Shared,
    rx: &Receiver<Input>,
    publishers: &Publishers,
    jobs: &Sender<DiagnosisJob>,
) {
    let mut next_publish = Instant::now() + shared.lock().publish_period;
    let mut drops_seen = 0;
    loop {
        let timeout = next_publish.saturating_duration_since(Instant::now());
        let first = match rx.recv_timeout(timeout) {
            Ok(input) => Some(input),
            Err(RecvTimeoutError::Timeout) => None,
            Err(RecvTimeoutError::Disconnected) => break,
        };
        let mut analysis = shared.lock();
        let mut next = first;
        while let Some(input) = next {
            analysis = shared.when_taking(analysis);
            analysis.take(input);
            shared.queued.fetch_sub(1, Ordering::SeqCst);
            next = rx.try_recv().ok();
        }
        analysis.apply_controls();
        if Instant::now() >= next_publish {
            let drops = analysis.drops.load(Ordering::Relaxed);
            let (array, states, mut latencies) = analysis.publish_round(drops - drops_seen, jobs);
            drops_seen = drops;
            next_publish += analysis.publish_period;
            if next_publish < Instant::now() {
                next_publish = Instant::now() + analysis.publish_period;
            }
            drop(analysis);
            publishers.publish(array, states, percentiles_ms(&mut latencies));
        }
    }
    // The queue is closed and drained (the node is stopping): the last line must be whole.
    let mut analysis = shared.lock();
    if let Some(d) = analysis.dump.take() {
        if let Err(e) = d.finish() {
            analysis.log.warn(&format!("dump_json: {e}"));
        }
    }
}

/// The analysis: the monitor and the publishers, driven by the receive loop or the analysis
/// thread (whichever holds [`Shared::analysis`]).
struct Analysis {
    monitor: Monitor,
    settings: MonitorSettings,
    publish_period: Duration,
    clock: NodeClock,
    log: Log,
    drops: Arc<AtomicU64>,
    /// The stamps' period for the parameter validator ([`measured_period`]).
    period_bits: Arc<AtomicU64>,
    dump: Option<DumpWriter>,
    latency: Latency,
    /// Parameter changes from the parameter services.
    params: Receiver<Control>,
}

impl Analysis {
    /// One input into the monitor, then the parameter changes waiting (between two samples).
    fn take(&mut self, input: Input) {
        match input {
            Input::Imu {
                sample,
                frame_id,
                receive_ns,
                arrived_ns,
            } => {
                for line in self.monitor.push(sample, &frame_id, receive_ns) {
                    self.log.warn(line);
                }
                self.latency.record((wall_ns() - arrived_ns) as f64 * 1e-9);
                if let Some(p) = self.monitor.sample_period_s() {
                    self.period_bits.store(p.to_bits(), Ordering::Relaxed);
                }
                if self.dump.is_some() {
                    self.dump_rows();
                }
            }
            Input::Temperature(reading) => self.monitor.push_temperature(&reading),
        }
        self.apply_controls();
    }

    /// Applies the parameter changes that have arrived.
    fn apply_controls(&mut self) {
        while let Ok(control) = self.params.try_recv() {
            match control {
                Control::Node(name, value) => self.apply(&name, &value),
                Control::Davar(name, config) => {
                    match self.monitor.reconfigure(Change::Davar(config)) {
                        Ok(()) => self
                            .log
                            .info(&format!("{name} changed: DAVAR pipeline restarted")),
                        Err(e) => self.log.warn(&format!("{name} not applied: {e}")),
                    }
                }
            }
        }
    }

    /// A publication: the `new_drops` since the last one counted, the next diagnosis due
    /// started (sent to `jobs`), the dump flushed; returns `/diagnostics`, the axis states and a
    /// copy of the latencies, to publish once the lock is released.
    fn publish_round(
        &mut self,
        new_drops: u64,
        jobs: &Sender<DiagnosisJob>,
    ) -> (DiagnosticArray, Vec<AxisState>, Vec<f64>) {
        if let Some(line) = self.monitor.add_drops(new_drops) {
            self.log.warn(line);
        }
        let now = self.clock.now_ns();
        if let Some(job) = self.monitor.start_diagnosis(now) {
            if let Err(mpsc::SendError(job)) = jobs.send(job) {
                // The diagnosis thread is gone: diagnose here rather than lose the record.
                let done = job.run();
                self.monitor.finish_diagnosis(done);
            }
        }
        let (array, states, line) = self.monitor.publication(now);
        if let Some(line) = line {
            self.log.warn(line);
        }
        // Rows reach the file at each publication, so that it can be read while the node runs.
        if let Some(Err(e)) = self.dump.as_mut().map(DumpWriter::flush) {
            self.log
                .warn(&format!("dump_json: {e}; no more rows are written"));
            self.dump = None;
        }
        (array, states, self.latency.ring.clone())
    }

    fn dump_rows(&mut self) {
        let Some(dump) = self.dump.as_mut() else {
            return;
        };
        for row in self.monitor.drain_rows() {
            if let Err(e) = dump.write(&row.axis, row.analysis_time_s, &row) {
                self.log
                    .warn(&format!("dump_json: {e}; no more rows are written"));
                self.dump = None;
                return;
            }
        }
    }

    fn apply(&mut self, name: &str, value: &ParameterValue) {
        match (name, value) {
            ("publish_rate_hz", ParameterValue::Double(hz)) => {
                self.publish_period = Duration::from_secs_f64(1.0 / hz);
            }
            ("stale_timeout_s", ParameterValue::Double(s)) => {
                self.settings.stale_timeout_s = *s;
                self.monitor.set_settings(self.settings);
            }
            ("diagnosis_period_s", ParameterValue::Double(s)) => {
                self.settings.diagnosis_period_s = *s;
                self.monitor.set_settings(self.settings);
            }
            ("diagnosis_cpu_share", ParameterValue::Double(share)) => {
                self.settings.diagnosis_cpu_share = *share;
                self.monitor.set_settings(self.settings);
            }
            (name, ParameterValue::String(s)) if name == "model" || name.starts_with("model.") => {
                let axis = name.strip_prefix("model.").and_then(|a| a.parse().ok());
                let change = Change::Model {
                    axis,
                    spec: s.clone(),
                };
                match self.monitor.reconfigure(change) {
                    Ok(()) => self.log.info(&format!("{name} = {s}")),
                    Err(e) => self.log.warn(&format!("{name} = {s} not applied: {e}")),
                }
            }
            _ => self
                .log
                .warn(&format!("parameter {name} = {value:?} has no live effect")),
        }
    }
}

/// The node's publishers, used by the analysis thread without the analysis lock.
struct Publishers {
    diagnostics: Publisher<DiagnosticArray>,
    states: Vec<Publisher<AxisState>>,
    log: Log,
}

impl Publishers {
    /// Publishes `/diagnostics`, with the receive-to-update latency's (p50, p99) in ms added to
    /// each status, and the axis states.
    fn publish(
        &self,
        mut array: DiagnosticArray,
        states: Vec<AxisState>,
        latency: Option<(f64, f64)>,
    ) {
        if let Some((p50, p99)) = latency {
            for status in &mut array.status {
                status
                    .values
                    .push(KeyValue::new("latency_p50_ms", format!("{p50:.3}")));
                status
                    .values
                    .push(KeyValue::new("latency_p99_ms", format!("{p99:.3}")));
            }
        }
        if let Err(e) = self.diagnostics.publish(array) {
            self.log.warn(&format!("publishing /diagnostics: {e:?}"));
        }
        for state in states {
            let index = state.axis.parse::<crate::signal::Axis>().map(|a| a.index());
            if let Some(publisher) = index.ok().and_then(|i| self.states.get(i)) {
                if let Err(e) = publisher.publish(state) {
                    self.log.warn(&format!("publishing axis state: {e:?}"));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_take_is_timed_just_after_the_last_message_its_first_may_wait_for() {
        let batching = Batching { period: Duration::from_micros(800), full: 25 };
        let us = 1_000;
        // 2 kHz: the next two are due 500 and 1 000 µs after the latest, the first may wait
        // 800 µs: the take comes a quarter gap after the second, 1 125 µs after the latest
        // (here taken 30 µs after it arrived).
        assert_eq!(batching.wait(0, 500 * us, 30 * us), Duration::from_micros(1_095));
        // 4 kHz: three (the first waits 2·250 + 62.5 µs).
        assert_eq!(batching.wait(0, 250 * us, 0), Duration::from_nanos(812_500));
        // 1.43 kHz: one, a quarter gap after it is due.
        assert_eq!(batching.wait(0, 700 * us, 0), Duration::from_micros(875));
        // Late (a slow take): what is left, down to nothing.
        assert_eq!(batching.wait(0, 500 * us, 1_100 * us), Duration::from_micros(25));
        assert_eq!(batching.wait(0, 500 * us, 2_000 * us), Duration::ZERO);
        // A wall clock stepped back by a second: no longer than from the latest arrival.
        assert_eq!(batching.wait(0, 500 * us, -1_000_000 * us), Duration::from_micros(1_125));
    }
}
