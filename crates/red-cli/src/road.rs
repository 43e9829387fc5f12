//! The road options shared by the `drive` subcommands.

use std::path::PathBuf;

use clap::Args;
use red_drive::DriveConfig;

/// The road: settings file and layout seed.
#[derive(Debug, Args)]
pub struct TrackArgs {
    /// Settings of the scenario (JSON of `DriveConfig`; missing fields take
    /// their defaults).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Seed of the road's layout (overrides the config's `track_seed`).
    #[arg(long)]
    pub track_seed: Option<u64>,
}

impl TrackArgs {
    /// The road the user asked for, if any option was given (a demo file
    /// otherwise brings its own).
    pub fn requested(&self) -> anyhow::Result<Option<DriveConfig>> {
        if self.config.is_some() || self.track_seed.is_some() {
            load_config(self).map(Some)
        } else {
            Ok(None)
        }
    }
}

/// The road of `track`: the settings file (or the default road) with the
/// track seed given.
pub fn load_config(track: &TrackArgs) -> anyhow::Result<DriveConfig> {
    let mut config: DriveConfig = crate::read_json(track.config.as_deref(), "the drive config")?;
    if let Some(s) = track.track_seed {
        config.track_seed = s;
    }
    config.validate()?;
    Ok(config)
}
