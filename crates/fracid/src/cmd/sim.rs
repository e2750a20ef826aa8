//! `fracid sim` (being written).
use anyhow::Result;

/// Options of `fracid sim`.
#[derive(Debug, clap::Args)]
pub struct SimArgs {}

/// Run `fracid sim`.
pub fn run(_a: SimArgs) -> Result<()> {
    anyhow::bail!("fracid sim is not built yet")
}
