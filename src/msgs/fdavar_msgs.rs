//! `fdavar_msgs/msg/*`: the typed per-axis state `fdavar_node` publishes on `~/<axis>/state`.
//!
//! The definitions live in the ament interface package `msg/` (built by colcon for ROS users);
//! these are their serde mirrors, and each [`MsgDef`] text *is* its `.msg` file (`include_str!`).
//! Each mirror also states its fields ([`Fields`]); a test checks those against the `.msg` file and
//! against the struct's serde field order, so that the three cannot drift apart.

use super::std_msgs::{Header, HEADER};
use super::{MsgDef, RosMessage};
use serde::{Deserialize, Serialize};

/// The fields of a mirror in `.msg` order: (ROS type as written in the `.msg` file, field name).
///
/// Why: serde knows the field names but not their ROS types; this list is what the test compares
/// with the `.msg` file, type by type.
pub trait Fields {
    /// (type, name) pairs.
    const FIELDS: &'static [(&'static str, &'static str)];
}

/// `fdavar_msgs/msg/AxisState`: one F-DAVAR update of one IMU axis.
///
/// Why: `/diagnostics` carries text for people; this carries the numbers for programs (the DAVAR
/// row with its confidence intervals, the fitted coefficients, where the model fails).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AxisState {
    /// `stamp` = analysis time t (sensor clock); `frame_id` = the IMU's frame.
    pub header: Header,
    /// Axis name (`gyro_x` … `accel_z`).
    pub axis: String,
    /// Analysis time t, seconds from the first sample received.
    pub analysis_time_s: f64,
    /// Window length W(t), samples.
    pub window_length: u32,
    /// F(t) (seed Eq. 2).
    pub f_value: f64,
    /// F̃, the reference F moves around.
    pub f_reference: f64,
    /// Nominal sample period τ0, seconds.
    pub sample_period_s: f64,
    /// The DAVAR row σ²(t, τ).
    pub row: Vec<DavarPoint>,
    /// The model in force on this axis (effect ids).
    pub model: Vec<String>,
    /// Its coefficients fitted to the whole run, with 1σ.
    pub coefficients: Vec<Coefficient>,
    /// RMS normalised residual over the τ grid of the whole run (docs/design.md §5).
    pub fit_error: f64,
    /// The same over the τ grids of the run's spans pooled: whether the model holds in time (NaN
    /// while the run is too short to be checked on spans).
    pub span_fit_error: f64,
    /// Excess kurtosis of the white rate noise where it is heavier-tailed than Gaussian (isolated
    /// spikes), the fit's EDFs widened for it; 0 when Gaussian (docs/design.md §5).
    pub rate_excess_kurtosis: f64,
    /// Maximal τ intervals where |z| > 3.
    pub failing_tau: Vec<TauInterval>,
    /// Maximal time spans where the model fails, seconds from the first sample.
    pub failing_spans: Vec<TimeSpan>,
    /// Missing effects, best first.
    pub suggestions: Vec<Suggestion>,
    /// IMU messages received when the diagnosis ran (`fdavar diagnose --first` reproduces it).
    pub diagnosed_messages: u64,
    /// Seconds of data the diagnosis covered (first to last sample).
    pub diagnosed_until_s: f64,
    /// Samples analysed since start.
    pub samples: u64,
    /// Samples dropped because the analysis queue was full.
    pub drops: u64,
    /// Gaps met in the stamps.
    pub gaps: u64,
}

/// The `.msg` definition of [`AxisState`]: the file `msg/msg/AxisState.msg`.
pub static AXIS_STATE: MsgDef = MsgDef {
    name: "fdavar_msgs/msg/AxisState",
    text: include_str!("../../msg/msg/AxisState.msg"),
    deps: &[
        &HEADER,
        &DAVAR_POINT,
        &COEFFICIENT,
        &TAU_INTERVAL,
        &TIME_SPAN,
        &SUGGESTION,
    ],
    type_hash: "",
};

impl RosMessage for AxisState {
    const DEF: &'static MsgDef = &AXIS_STATE;
}

impl Fields for AxisState {
    const FIELDS: &'static [(&'static str, &'static str)] = &[
        ("std_msgs/Header", "header"),
        ("string", "axis"),
        ("float64", "analysis_time_s"),
        ("uint32", "window_length"),
        ("float64", "f_value"),
        ("float64", "f_reference"),
        ("float64", "sample_period_s"),
        ("DavarPoint[]", "row"),
        ("string[]", "model"),
        ("Coefficient[]", "coefficients"),
        ("float64", "fit_error"),
        ("float64", "span_fit_error"),
        ("float64", "rate_excess_kurtosis"),
        ("TauInterval[]", "failing_tau"),
        ("TimeSpan[]", "failing_spans"),
        ("Suggestion[]", "suggestions"),
        ("uint64", "diagnosed_messages"),
        ("float64", "diagnosed_until_s"),
        ("uint64", "samples"),
        ("uint64", "drops"),
        ("uint64", "gaps"),
    ];
}

/// `fdavar_msgs/msg/DavarPoint`: σ²(t, τ) with its confidence interval and EDF.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct DavarPoint {
    /// τ, seconds.
    pub tau_s: f64,
    /// Allan variance at τ.
    pub avar: f64,
    /// Lower end of the 68.3 % interval.
    pub avar_low: f64,
    /// Upper end of the 68.3 % interval.
    pub avar_high: f64,
    /// Equivalent degrees of freedom.
    pub edf: f64,
}

/// The `.msg` definition of [`DavarPoint`]: the file `msg/msg/DavarPoint.msg`.
pub static DAVAR_POINT: MsgDef = MsgDef {
    name: "fdavar_msgs/msg/DavarPoint",
    text: include_str!("../../msg/msg/DavarPoint.msg"),
    deps: &[],
    type_hash: "",
};

impl RosMessage for DavarPoint {
    const DEF: &'static MsgDef = &DAVAR_POINT;
}

impl Fields for DavarPoint {
    const FIELDS: &'static [(&'static str, &'static str)] = &[
        ("float64", "tau_s"),
        ("float64", "avar"),
        ("float64", "avar_low"),
        ("float64", "avar_high"),
        ("float64", "edf"),
    ];
}

/// `fdavar_msgs/msg/Coefficient`: one parameter of one effect, SI units.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Coefficient {
    /// Effect id, e.g. `white`.
    pub effect: String,
    /// Parameter name, e.g. `n`.
    pub name: String,
    /// Value in `unit`.
    pub value: f64,
    /// 1σ uncertainty in `unit`; NaN when the fit gives none.
    pub sigma: f64,
    /// SI unit.
    pub unit: String,
}

/// The `.msg` definition of [`Coefficient`]: the file `msg/msg/Coefficient.msg`.
pub static COEFFICIENT: MsgDef = MsgDef {
    name: "fdavar_msgs/msg/Coefficient",
    text: include_str!("../../msg/msg/Coefficient.msg"),
    deps: &[],
    type_hash: "",
};

impl RosMessage for Coefficient {
    const DEF: &'static MsgDef = &COEFFICIENT;
}

impl Fields for Coefficient {
    const FIELDS: &'static [(&'static str, &'static str)] = &[
        ("string", "effect"),
        ("string", "name"),
        ("float64", "value"),
        ("float64", "sigma"),
        ("string", "unit"),
    ];
}

/// `fdavar_msgs/msg/TauInterval`: a closed interval of τ, seconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TauInterval {
    /// Lower end, seconds.
    pub low_s: f64,
    /// Upper end, seconds.
    pub high_s: f64,
}

/// The `.msg` definition of [`TauInterval`]: the file `msg/msg/TauInterval.msg`.
pub static TAU_INTERVAL: MsgDef = MsgDef {
    name: "fdavar_msgs/msg/TauInterval",
    text: include_str!("../../msg/msg/TauInterval.msg"),
    deps: &[],
    type_hash: "",
};

impl RosMessage for TauInterval {
    const DEF: &'static MsgDef = &TAU_INTERVAL;
}

impl Fields for TauInterval {
    const FIELDS: &'static [(&'static str, &'static str)] =
        &[("float64", "low_s"), ("float64", "high_s")];
}

/// `fdavar_msgs/msg/TimeSpan`: a closed interval of time, seconds from the first sample.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TimeSpan {
    /// Start, seconds.
    pub start_s: f64,
    /// End, seconds.
    pub end_s: f64,
}

/// The `.msg` definition of [`TimeSpan`]: the file `msg/msg/TimeSpan.msg`.
pub static TIME_SPAN: MsgDef = MsgDef {
    name: "fdavar_msgs/msg/TimeSpan",
    text: include_str!("../../msg/msg/TimeSpan.msg"),
    deps: &[],
    type_hash: "",
};

impl RosMessage for TimeSpan {
    const DEF: &'static MsgDef = &TIME_SPAN;
}

impl Fields for TimeSpan {
    const FIELDS: &'static [(&'static str, &'static str)] =
        &[("float64", "start_s"), ("float64", "end_s")];
}

/// `fdavar_msgs/msg/Suggestion`: an effect the model misses.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Suggestion {
    /// Effect id.
    pub effect: String,
    /// Its estimated parameters.
    pub params: Vec<Coefficient>,
    /// fit_error once the effect is added (with `given`).
    pub fit_error_after: f64,
    /// span_fit_error once the effect is added (with `given`).
    pub span_fit_error_after: f64,
    /// One plain sentence of physics.
    pub explanation: String,
    /// The effects added before this one was weighed (empty for the first suggestion).
    pub given: Vec<String>,
}

/// The `.msg` definition of [`Suggestion`]: the file `msg/msg/Suggestion.msg`.
pub static SUGGESTION: MsgDef = MsgDef {
    name: "fdavar_msgs/msg/Suggestion",
    text: include_str!("../../msg/msg/Suggestion.msg"),
    deps: &[&COEFFICIENT],
    type_hash: "",
};

impl RosMessage for Suggestion {
    const DEF: &'static MsgDef = &SUGGESTION;
}

impl Fields for Suggestion {
    const FIELDS: &'static [(&'static str, &'static str)] = &[
        ("string", "effect"),
        ("Coefficient[]", "params"),
        ("float64", "fit_error_after"),
        ("float64", "span_fit_error_after"),
        ("string", "explanation"),
        ("string[]", "given"),
    ];
}
