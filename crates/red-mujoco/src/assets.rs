//! Where Gymnasium's model files are found.
//!
//! The folder is the run-time environment variable [`ASSETS_ENV_VAR`] if it
//! is set, else the value the same variable had when this crate was built
//! (`.cargo/config.toml` points it at `.mujoco/assets` of the repository,
//! which `scripts/setup-mujoco.sh` fills from the `gymnasium` wheel).

use std::path::PathBuf;

pub use crate::error::ASSETS_ENV_VAR;
use crate::{Error, Result};

/// The folder configured when the crate was built, if any.
const BUILD_TIME_DIR: Option<&str> = option_env!("RED_MUJOCO_ASSETS");

/// The folder of the model files and, in words, where that choice came from.
/// `None` when neither the run-time variable nor the build-time default is
/// set.
pub fn assets_dir() -> Option<(PathBuf, String)> {
    if let Some(dir) = std::env::var_os(ASSETS_ENV_VAR).filter(|d| !d.is_empty()) {
        return Some((
            PathBuf::from(dir),
            format!("from the environment variable {ASSETS_ENV_VAR}"),
        ));
    }
    BUILD_TIME_DIR
        .filter(|d| !d.is_empty())
        .map(|d| (PathBuf::from(d), "the folder set at build time".to_string()))
}

/// The full path of model file `file_name` (for example `"hopper.xml"`).
///
/// # Errors
/// [`Error::AssetNotFound`] if no folder is configured or the file is not in
/// it; the message says to run `scripts/setup-mujoco.sh`.
pub fn model_path(file_name: &str) -> Result<PathBuf> {
    let Some((dir, source_of_dir)) = assets_dir() else {
        return Err(Error::AssetNotFound {
            path: PathBuf::from(file_name),
            source_of_dir: format!("{ASSETS_ENV_VAR} is not set"),
        });
    };
    let path = dir.join(file_name);
    if path.is_file() {
        Ok(path)
    } else {
        Err(Error::AssetNotFound {
            path,
            source_of_dir,
        })
    }
}
