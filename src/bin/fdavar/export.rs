//! `fdavar export kalibr|openvins|vins BAG_OR_JSON [--inflate X] [--model SPEC] [--topic T]`:
//! the fitted IMU noise in a state estimator's config keys ([`fdavar::report::export`]).

use crate::{Outcome, UsageError};
use anyhow::Context;
use fdavar::bag::BagReader;
use fdavar::model::{effects, ModelSpec};
use fdavar::report::export::{AxisNoise, ExportFormat, ImuNoise};
use fdavar::signal::Axis;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Write the fitted IMU noise in the config keys of Kalibr, OpenVINS or VINS-Fusion.
///
/// Per sensor, the white noise density N (rad/s/√Hz; accel m/s²/√Hz) and the bias random walk
/// density K (rad/s/√s = rad/s²/√Hz; accel m/s³/√Hz), continuous time — the values these
/// estimators want, no unit factor — the largest of the sensor's three axes. kalibr: imu.yaml
/// (accelerometer_noise_density, accelerometer_random_walk, gyroscope_noise_density,
/// gyroscope_random_walk, rostopic, update_rate); openvins: the same keys under imu0: of
/// kalibr_imu_chain.yaml (keep that file's other keys); vins: imu_topic, acc_n, gyr_n, acc_w,
/// gyr_w. A bag is fitted here as `fdavar fit` does; a JSON is what `fit --json` or
/// `diagnose --json` printed (`-` reads it from stdin). Exit 3 when samples were left out or a
/// term is not resolved (0 on every axis of a sensor: record longer, or set it by hand).
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// Estimator: kalibr, openvins or vins.
    #[arg(value_parser = clap::builder::PossibleValuesParser::new(ExportFormat::ALL.map(ExportFormat::name)))]
    pub format: String,
    /// A rosbag2 recording (directory, .mcap, .db3) to fit, or a fit/diagnose JSON file (- = stdin).
    pub input: PathBuf,
    /// Multiply every density by X (variances by X²) for unmodelled real-world effects; OpenVINS'
    /// calibration guide suggests 10 to 20. Default 1: as measured.
    #[arg(long, default_value_t = 1.0, value_name = "X")]
    pub inflate: f64,
    /// Model to fit a bag with; must hold N (white) or bandwidth (a sensor's low-pass: its n is
    /// then the noise density), and K (random_walk).
    #[arg(long, default_value = ModelSpec::DEFAULT, value_parser = crate::model_spec_arg)]
    pub model: String,
    /// IMU topic: read from the bag and written to the file (default: the bag's only
    /// sensor_msgs/msg/Imu topic; required with JSON input).
    #[arg(long)]
    pub topic: Option<String>,
    /// Sample rate written as update_rate, Hz (default: measured from the bag's stamps; required
    /// for kalibr and openvins with JSON input).
    #[arg(long, value_name = "HZ")]
    pub rate: Option<f64>,
    /// Write the file here instead of to stdout.
    #[arg(long, short, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

pub fn run(args: &Args) -> anyhow::Result<Outcome> {
    let format: ExportFormat = args.format.parse()?;
    let (noise, mut outcome) = if is_json(&args.input) {
        from_json(args, format)?
    } else {
        from_bag(args)?
    };
    let noise = noise.inflated(args.inflate).map_err(|e| UsageError(format!("--inflate: {e}")))?;
    let yaml = noise.to_yaml(format)?;
    match &args.out {
        Some(path) => std::fs::write(path, &yaml).with_context(|| format!("writing {}", path.display()))?,
        None => std::io::stdout().lock().write_all(yaml.as_bytes()).context("writing output")?,
    }
    let unresolved = noise.unresolved();
    if !unresolved.is_empty() {
        eprintln!(
            "fdavar: warning: {} written as 0: the fit did not resolve it on any axis of the sensor (an estimator would take that noise as absent); record longer or set it by hand",
            unresolved.join(", ")
        );
        outcome = Outcome::Warnings;
    }
    Ok(outcome)
}

/// `-`, a `.json` file, or a file whose first non-blank byte is `{`.
fn is_json(path: &Path) -> bool {
    if path == Path::new("-") || path.extension().is_some_and(|e| e == "json") {
        return true;
    }
    let mut head = [0u8; 64];
    path.is_file()
        && std::fs::File::open(path)
            .and_then(|mut f| f.read(&mut head))
            .is_ok_and(|n| head[..n].iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{'))
}

/// Fits every axis of the bag with the model, as `fdavar fit` does.
fn from_bag(args: &Args) -> anyhow::Result<(ImuNoise, Outcome)> {
    let spec = ModelSpec::parse(&args.model).context("invalid --model")?;
    let holds = |id: &str| spec.ids().iter().any(|e| e == id);
    if !holds(effects::id::WHITE) && !holds(effects::id::BANDWIDTH) {
        return Err(UsageError(format!("--model {}: export needs N (white) or bandwidth", args.model)).into());
    }
    if !holds(effects::id::RANDOM_WALK) {
        return Err(UsageError(format!("--model {}: export needs K (random_walk)", args.model)).into());
    }
    let topic = BagReader::open(&args.input)
        .with_context(|| format!("cannot open {}", args.input.display()))?
        .imu_topic(args.topic.as_deref())?
        .name
        .clone();
    let model = std::slice::from_ref(&args.model);
    let mut analysis = crate::fit::load(&crate::fit::Source::whole(&args.input, model, Some(&topic)), None)?;
    let mut fits = Vec::new();
    for axis in Axis::ALL {
        fits.push(analysis.fit(axis).with_context(|| format!("cannot fit {axis}"))?);
    }
    let outcome = crate::fit::outcome(&analysis, &fits, false, "`fdavar diagnose` suggests what is missing");
    let axes = fits.iter().map(AxisNoise::from_fit).collect::<Result<Vec<_>, _>>()?;
    let tau0 = analysis.sample_period_s().context("too few IMU samples to know their rate")?;
    let rate = args.rate.unwrap_or(1.0 / tau0);
    Ok((ImuNoise::from_axes(&axes, &topic, Some(rate))?, outcome))
}

/// Reads the JSON `fdavar fit --json` / `diagnose --json` printed; topic and rate from the flags.
fn from_json(args: &Args, format: ExportFormat) -> anyhow::Result<(ImuNoise, Outcome)> {
    let name = args.input.display();
    let text = if args.input == Path::new("-") {
        let mut s = String::new();
        std::io::stdin().read_to_string(&mut s).context("reading stdin")?;
        s
    } else {
        std::fs::read_to_string(&args.input).with_context(|| format!("reading {name}"))?
    };
    let doc: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{name} is not JSON"))?;
    let axes = AxisNoise::from_report_json(&doc).with_context(|| format!("in {name}"))?;
    let topic = args
        .topic
        .as_deref()
        .ok_or_else(|| UsageError(format!("--topic is needed with JSON input ({name} names no topic)")))?;
    if format.needs_rate() && args.rate.is_none() {
        return Err(UsageError(format!("--rate HZ is needed for {format} with JSON input ({name} holds no sample rate)")).into());
    }
    Ok((ImuNoise::from_axes(&axes, topic, args.rate).with_context(|| format!("in {name}"))?, Outcome::Ok))
}
