//! `fdavar fit` (not built yet; see its issue).

use crate::Outcome;

/// `fdavar fit`: not built yet.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {}

pub fn run(_args: &Args) -> anyhow::Result<Outcome> {
    anyhow::bail!("'fdavar fit' is not built yet")
}
