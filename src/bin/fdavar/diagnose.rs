//! `fdavar diagnose` (not built yet; see its issue).

use crate::Outcome;

/// `fdavar diagnose`: not built yet.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {}

pub fn run(_args: &Args) -> anyhow::Result<Outcome> {
    anyhow::bail!("'fdavar diagnose' is not built yet")
}
