//! `fdavar play` (not built yet; see its issue).

use crate::Outcome;

/// `fdavar play`: not built yet.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {}

pub fn run(_args: &Args) -> anyhow::Result<Outcome> {
    anyhow::bail!("'fdavar play' is not built yet")
}
