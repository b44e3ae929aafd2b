//! Rendering: figures (PNG + SVG), text tables, CSV, and display units. No maths here.
//!
//! The renderers ([`figure`], [`table`], [`units`], [`export`]) take *plain data* — vectors of
//! (τ, σ) pairs, times, window lengths — defined here, not the fitter's or the DAVAR engine's types,
//! so a figure can be made from a JSON dump of a run (every figure struct is
//! `serde`-serialisable). [`fit`] and [`davar`] are the bridges: they read a fitted model or the
//! pipeline's rows and hand plain data to the renderers. The arrow stays one way (`model`,
//! `pipeline` → `report`); nothing in the estimators reaches into `report`.
//!
//! - [`figure`]: the Allan deviation with its confidence band, model, terms and z residuals
//!   ([`figure::AllanFigure`], before/after [`figure::AllanComparison`]), the DAVAR surface heatmap
//!   ([`figure::DavarSurface`]) and the F value / window length trace ([`figure::WindowTrace`],
//!   the seed's Figs. 3–4). Each writer produces `<stem>.png` and `<stem>.svg`.
//! - [`units`]: SI coefficients to the seed's display units (Q µrad, N °/√h, B °/h, K °/h^1.5,
//!   R °/h²) and to Kalibr's IMU noise terms.
//! - [`export`]: the fitted N and K per sensor in Kalibr, OpenVINS and VINS-Fusion config keys.
//! - [`davar`]: the DAVAR surface and window trace of a recording, gathered from its streamed rows
//!   in bounded memory.
//! - [`fit`]: the text of `fdavar fit`/`diagnose` (every number with its unit) and the CSV of
//!   the Allan curve, model and z per τ.
//! - [`table`]: aligned text tables and RFC 4180 CSV from the same rows; numbers formatted to
//!   significant digits.
//!
//! Fonts: text is rasterised with `ab_glyph` from the DejaVu Sans file bundled in
//! `assets/fonts/` (licence beside it), so figures look the same on every machine and need no
//! system font library (fontconfig/freetype). The rejected alternative, plotters' default `ttf`
//! feature, looks fonts up on the system and fails on a bare CI image.
use std::path::PathBuf;

pub mod davar;
pub mod export;
pub mod figure;
pub mod fit;
pub mod table;
pub mod units;

/// Why a report could not be rendered.
///
/// Input problems name the figure, the field and the index of the offending value, so the caller
/// can tell which of its own numbers is wrong; drawing and file problems name the path.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// A field the figure needs has no entries.
    #[error("{figure}: `{field}` is empty, nothing to draw")]
    Empty {
        /// Which figure (e.g. "allan", "davar surface").
        figure: &'static str,
        /// Which field of the input.
        field: String,
    },
    /// A value is NaN or infinite where a number is required.
    #[error("{figure}: `{field}[{index}]` = {value} is not a finite number")]
    NotFinite {
        /// Which figure.
        figure: &'static str,
        /// Which field of the input.
        field: String,
        /// Position of the value in that field.
        index: usize,
        /// The value found.
        value: f64,
    },
    /// A value that goes on a logarithmic axis is zero or negative.
    #[error("{figure}: `{field}[{index}]` = {value} must be > 0 (it goes on a logarithmic axis)")]
    NotPositive {
        /// Which figure.
        figure: &'static str,
        /// Which field of the input.
        field: String,
        /// Position of the value in that field.
        index: usize,
        /// The value found.
        value: f64,
    },
    /// Two fields that must run in step have different lengths.
    #[error("{figure}: `{field}` has {got} entries, expected {expected} (one per `{per}`)")]
    LengthMismatch {
        /// Which figure.
        figure: &'static str,
        /// The field with the wrong length.
        field: String,
        /// The field whose length it must match.
        per: &'static str,
        /// The length it must have.
        expected: usize,
        /// The length it has.
        got: usize,
    },
    /// An interval or band has its ends the wrong way round (low > high).
    #[error("{figure}: `{field}[{index}]` is reversed: {low} > {high}")]
    Reversed {
        /// Which figure.
        figure: &'static str,
        /// Which field of the input.
        field: String,
        /// Position of the interval.
        index: usize,
        /// Its lower end.
        low: f64,
        /// Its upper end.
        high: f64,
    },
    /// A sequence that must increase strictly (times, τ) does not.
    #[error(
        "{figure}: `{field}` must increase strictly, but entry {index} is {value} after {previous}"
    )]
    NotIncreasing {
        /// Which figure.
        figure: &'static str,
        /// Which field of the input.
        field: String,
        /// Position of the offending value.
        index: usize,
        /// The value before it.
        previous: f64,
        /// The value found.
        value: f64,
    },
    /// An axis range that cannot be drawn: a log axis over more than 40 decades, values beyond
    /// 1e±300, or a linear span too small to resolve against the size of its values.
    #[error("{figure}: `{field}` from {low:e} to {high:e} cannot be drawn: {why}")]
    UnplottableRange {
        /// Which figure.
        figure: &'static str,
        /// Which field of the input.
        field: String,
        /// Smallest value.
        low: f64,
        /// Largest value.
        high: f64,
        /// What is wrong with the range.
        why: &'static str,
    },
    /// The output directory could not be created.
    ///
    /// The I/O error is the [`std::error::Error::source`], not in the message: a report of the
    /// chain (anyhow's, the CLI's) printed it twice.
    #[error("cannot create directory {path}")]
    CreateDir {
        /// The directory.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The plotting backend failed (usually an unwritable file).
    #[error("cannot draw {path}: {message}")]
    Draw {
        /// The file being written.
        path: PathBuf,
        /// The backend's message.
        message: String,
    },
    /// The bundled font file could not be parsed (a corrupted checkout).
    #[error("the bundled font assets/fonts/DejaVuSans.ttf could not be loaded; re-check out the repository")]
    Font,
}
