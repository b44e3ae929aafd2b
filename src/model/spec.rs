//! `ModelSpec`: which effects a model contains, as plain data.
//!
//! A spec is what the user asked for (`N,B,K,sinusoid`), not a fitted model: it holds the canonical
//! effect ids, compares with `==`, and survives a serde round trip, so the CLI, the node's
//! parameters and the reports can all carry it. Names are resolved through the effect registry,
//! so a new effect is usable in a spec as soon as it is in [`effects::REGISTRY`].

use crate::model::effects::{self, Domain, EffectKind};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// The effects of a noise model, by canonical id, in the order given (duplicates removed).
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(transparent)]
pub struct ModelSpec {
    effects: Vec<String>,
}

/// A model spec that names an effect the registry does not know, or names nothing.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum SpecError {
    /// A name that is neither an effect id nor an alias.
    #[error("unknown effect '{name}' in model spec (known: {known})")]
    UnknownEffect {
        /// The name as given.
        name: String,
        /// The known ids and aliases, comma-separated.
        known: String,
    },
    /// The spec is empty.
    #[error("empty model spec: give effect names or aliases, e.g. N,B,K")]
    Empty,
    /// A spec with an empty term between its names, e.g. `N,,B` (issue 13: it was read as
    /// `N,B`, hiding a name the user meant to give).
    #[error("empty effect name in model spec '{0}' (two commas in a row, or one at an end)")]
    EmptyTerm(String),
    /// A spec of time-domain effects only, e.g. `bias_step`: the fitter removes those from the
    /// samples and fits the Allan variance of the rest with the spectral effects, so without one
    /// the model's Allan variance is zero and every z infinite.
    #[error(
        "model spec '{spec}' has no noise term: time-domain effects ({time_domain}) are removed \
         from the samples before the Allan variance of the rest is fitted with the spectral \
         effects ({spectral}); add one, e.g. N,B,K,{spec}"
    )]
    NoNoiseTerm {
        /// The spec as given.
        spec: String,
        /// The registry's spectral kinds, comma-separated.
        spectral: String,
        /// The registry's time-domain kinds, comma-separated.
        time_domain: String,
    },
    /// `AXIS=SPEC` with a name that is not an axis.
    #[error("unknown axis '{0}' in '{0}=…' (axes: gyro_x gyro_y gyro_z accel_x accel_y accel_z)")]
    UnknownAxis(String),
}

/// The model of each axis ([`crate::signal::Axis::ALL`] order) from `--model` values: `SPEC` sets
/// every axis, `AXIS=SPEC` one axis (later values win); axes no value names get `default`.
///
/// ```
/// use fdavar::model::spec::axis_models;
/// let m = axis_models(&["N,B".into(), "gyro_x=N,B,K,sinusoid".into()], "N,B,K").unwrap();
/// assert_eq!(m[0].ids(), ["white", "bias_instability", "random_walk", "sinusoid"]);
/// assert_eq!(m[1].ids(), ["white", "bias_instability"]);
/// ```
///
/// # Errors
/// [`SpecError`] for an unknown effect or axis, or an empty spec.
pub fn axis_models(values: &[String], default: &str) -> Result<[ModelSpec; 6], SpecError> {
    let default = ModelSpec::parse(default)?;
    let mut models: [ModelSpec; 6] = std::array::from_fn(|_| default.clone());
    for value in values {
        match value.split_once('=') {
            Some((axis, spec)) => {
                let axis: crate::signal::Axis = axis
                    .trim()
                    .parse()
                    .map_err(|_| SpecError::UnknownAxis(axis.trim().to_string()))?;
                models[axis.index()] = ModelSpec::parse(spec)?;
            }
            None => {
                let spec = ModelSpec::parse(value)?;
                models.iter_mut().for_each(|m| *m = spec.clone());
            }
        }
    }
    Ok(models)
}

impl ModelSpec {
    /// The default model of `fdavar diagnose`: white noise, bias instability and rate random walk.
    pub const DEFAULT: &'static str = "N,B,K";

    /// Parses `N,B,K,sinusoid` against the crate's registry.
    ///
    /// # Errors
    /// [`SpecError::UnknownEffect`] naming the first unknown term, [`SpecError::Empty`],
    /// [`SpecError::EmptyTerm`] for an empty name between commas, [`SpecError::NoNoiseTerm`] for
    /// time-domain effects alone.
    pub fn parse(s: &str) -> Result<Self, SpecError> {
        Self::parse_in(s, effects::REGISTRY)
    }

    /// Parses against a given registry (tests and embedders with their own effect kinds).
    ///
    /// # Errors
    /// As [`ModelSpec::parse`].
    pub fn parse_in(s: &str, registry: &[&'static dyn EffectKind]) -> Result<Self, SpecError> {
        let names: Vec<&str> = s.split(',').map(str::trim).collect();
        if names.iter().all(|n| n.is_empty()) {
            return Err(SpecError::Empty);
        }
        if names.iter().any(|n| n.is_empty()) {
            return Err(SpecError::EmptyTerm(s.to_string()));
        }
        let spectral = |k: &&'static dyn EffectKind| k.domain() == Domain::Spectral;
        let (mut spec, mut any_spectral) = (ModelSpec::default(), false);
        for name in names {
            let kind = lookup(registry, name).ok_or_else(|| SpecError::UnknownEffect {
                name: name.to_string(),
                known: known_names(registry),
            })?;
            any_spectral |= spectral(&kind);
            spec = spec.with(kind.id());
        }
        if spec.effects.is_empty() {
            return Err(SpecError::Empty);
        }
        if !any_spectral {
            let names = |want: bool| {
                let kinds = registry.iter().filter(|k| spectral(k) == want);
                kinds.map(|k| k.alias().unwrap_or(k.id())).collect::<Vec<_>>().join(", ")
            };
            return Err(SpecError::NoNoiseTerm {
                spec: s.trim().to_string(),
                spectral: names(true),
                time_domain: names(false),
            });
        }
        Ok(spec)
    }

    /// The spec built from ids known to be canonical (e.g. from a fitted model).
    pub fn from_ids<I: IntoIterator<Item = S>, S: Into<String>>(ids: I) -> Self {
        ids.into_iter()
            .fold(ModelSpec::default(), |s, id| s.with(&id.into()))
    }

    /// The effect ids, in order.
    pub fn ids(&self) -> &[String] {
        &self.effects
    }

    /// True when the spec has effect `id`.
    pub fn contains(&self, id: &str) -> bool {
        self.effects.iter().any(|e| e == id)
    }

    /// This spec with `id` appended (unchanged if present).
    pub fn with(&self, id: &str) -> Self {
        let mut out = self.clone();
        if !out.contains(id) {
            out.effects.push(id.to_string());
        }
        out
    }

    /// The kinds of the spec's effects, looked up in `registry`.
    ///
    /// # Errors
    /// [`SpecError::UnknownEffect`] when an id is missing from `registry`.
    pub fn kinds(
        &self,
        registry: &[&'static dyn EffectKind],
    ) -> Result<Vec<&'static dyn EffectKind>, SpecError> {
        self.effects
            .iter()
            .map(|id| {
                lookup(registry, id).ok_or_else(|| SpecError::UnknownEffect {
                    name: id.clone(),
                    known: known_names(registry),
                })
            })
            .collect()
    }
}

fn lookup(registry: &[&'static dyn EffectKind], name: &str) -> Option<&'static dyn EffectKind> {
    registry
        .iter()
        .copied()
        .find(|k| k.id() == name || k.alias() == Some(name))
}

fn known_names(registry: &[&'static dyn EffectKind]) -> String {
    registry
        .iter()
        .map(|k| match k.alias() {
            Some(a) => format!("{} ({a})", k.id()),
            None => k.id().to_string(),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

impl FromStr for ModelSpec {
    type Err = SpecError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        ModelSpec::parse(s)
    }
}

impl fmt::Display for ModelSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.effects.join(","))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::REGISTRY as KINDS;

    #[test]
    fn parses_ids_and_aliases_in_order_without_duplicates() {
        let s = ModelSpec::parse_in(" N, B ,K,sinusoid,white", KINDS).unwrap();
        assert_eq!(
            s.ids(),
            ["white", "bias_instability", "random_walk", "sinusoid"]
        );
        assert_eq!(s.to_string(), "white,bias_instability,random_walk,sinusoid");
        assert_eq!(ModelSpec::parse_in(&s.to_string(), KINDS).unwrap(), s);
    }

    #[test]
    fn names_the_unknown_term() {
        let err = ModelSpec::parse_in("N,Bogus", KINDS).unwrap_err();
        assert!(matches!(&err, SpecError::UnknownEffect { name, .. } if name == "Bogus"));
        assert!(err.to_string().contains("white (N)"));
        assert_eq!(ModelSpec::parse_in(" , ", KINDS), Err(SpecError::Empty));
        for spec in ["N,,B", "N,B,", ",N", "N, ,B"] {
            let err = ModelSpec::parse_in(spec, KINDS).unwrap_err();
            assert_eq!(err, SpecError::EmptyTerm(spec.to_string()));
            assert_eq!(
                err.to_string(),
                format!("empty effect name in model spec '{spec}' (two commas in a row, or one at an end)")
            );
        }
    }

    #[test]
    fn a_model_needs_a_noise_term() {
        for spec in ["bias_step", "bias_step, noise_burst", "temperature,g_sensitivity"] {
            let err = ModelSpec::parse_in(spec, KINDS).unwrap_err();
            assert!(matches!(&err, SpecError::NoNoiseTerm { spec: s, .. } if s == spec), "{spec}: {err}");
            let text = err.to_string();
            assert!(text.contains("spectral effects (Q, N, B, K, sinusoid,") && text.contains("(R, bias_step, noise_burst,"), "{text}");
            assert!(text.ends_with(&format!("e.g. N,B,K,{spec}")), "{text}");
        }
        // One spectral term suffices, whichever it is.
        for spec in ["bias_step,sinusoid", "Q", "bandwidth,noise_burst"] {
            assert!(ModelSpec::parse_in(spec, KINDS).is_ok(), "{spec}");
        }
    }

    #[test]
    fn serde_round_trip() {
        let s = ModelSpec::parse_in("N,K", KINDS).unwrap();
        let j = serde_json::to_string(&s).unwrap();
        assert_eq!(j, r#"["white","random_walk"]"#);
        assert_eq!(serde_json::from_str::<ModelSpec>(&j).unwrap(), s);
    }
}
