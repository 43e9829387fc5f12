//! A check of the whole install: the MuJoCo library's version, the model
//! files, and a short run of every environment through red-core's env
//! checker, with what to do about each problem found.

use std::time::Instant;

use red_core::Env;
use red_core::check::{CheckConfig, check_env_with};
use red_mujoco::EnvId;

/// What [`check_install`] found: the report's lines and the problems, each
/// with what to do about it (none: everything works).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InstallReport {
    /// The lines to print, in order.
    pub lines: Vec<String>,
    /// The problems found.
    pub problems: Vec<String>,
}

/// Plays `env` through the env checker for `steps` steps (twice, compared
/// bit for bit); returns its environment steps per second.
fn speed<E: Env + ?Sized>(env: &mut E, steps: usize) -> red_core::Result<f64> {
    let config = CheckConfig {
        steps,
        ..CheckConfig::default()
    };
    let start = Instant::now();
    check_env_with(env, &config)?;
    Ok((2 * steps) as f64 / start.elapsed().as_secs_f64().max(1e-9))
}

/// Checks the install: the MuJoCo library against the version the bindings
/// expect, the model folder, and `steps` steps of each MuJoCo task and of
/// the driving scenario.
pub fn check_install(steps: usize) -> InstallReport {
    let mut lines = Vec::new();
    let mut problems = Vec::new();
    let found = red_mujoco::library_version();
    let expected = red_mujoco::EXPECTED_LIBRARY_VERSION;
    let mark = if found == expected { "ok" } else { "MISMATCH" };
    lines.push(format!(
        "MuJoCo library: {found} (bindings expect {expected}) {mark}"
    ));
    if let Some(dir) = option_env!("MUJOCO_DYNAMIC_LINK_DIR") {
        lines.push(format!("  linked from: {dir}"));
    }
    if found != expected {
        problems.push(format!(
            "MuJoCo {found} was loaded but {expected} is needed: run scripts/setup-mujoco.sh --force"
        ));
    }
    match red_mujoco::assets::assets_dir() {
        Some((dir, source)) => lines.push(format!("model files: {} ({source})", dir.display())),
        None => {
            lines.push("model files: no folder configured".into());
            problems.push("no model folder: run scripts/setup-mujoco.sh".into());
        }
    }
    lines.push(format!(
        "tiny run of each environment ({steps} random steps, twice):"
    ));
    let mut report = |name: &str, rate: std::result::Result<f64, String>, fix: &str| match rate {
        Ok(rate) => lines.push(format!("  {name:<16} ok  {rate:>10.0} steps/s")),
        Err(e) => {
            lines.push(format!("  {name:<16} FAILED: {e}"));
            problems.push(format!("{name} does not run ({e}){fix}"));
        }
    };
    for id in EnvId::ALL {
        let rate = id
            .make()
            .map_err(red_core::Error::from)
            .and_then(|mut env| speed(&mut env, steps));
        let fix = ": run scripts/setup-mujoco.sh";
        report(id.name(), rate.map_err(|e| e.to_string()), fix);
    }
    let drive = red_drive::make_env(&red_drive::DriveConfig::default())
        .map_err(red_core::Error::from)
        .and_then(|mut env| speed(&mut env, steps));
    report("drive", drive.map_err(|e| e.to_string()), "");
    InstallReport { lines, problems }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_install_works() {
        let r = check_install(20);
        assert!(r.problems.is_empty(), "{:?}", r.problems);
        assert!(
            r.lines
                .iter()
                .any(|l| l.contains("drive") && l.contains(" ok "))
        );
    }
}
