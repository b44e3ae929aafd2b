//! `fdavar simulate` (not built yet; see its issue).

use crate::Outcome;

/// `fdavar simulate`: not built yet.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {}

pub fn run(_args: &Args) -> anyhow::Result<Outcome> {
    anyhow::bail!("'fdavar simulate' is not built yet")
}
