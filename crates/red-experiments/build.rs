//! Embeds the folder of the MuJoCo shared library (`MUJOCO_DYNAMIC_LINK_DIR`,
//! set in `.cargo/config.toml` and filled by `scripts/setup-mujoco.sh`) as an
//! rpath of this crate's tests, benches and examples, so that they run
//! without `LD_LIBRARY_PATH`.

use std::path::PathBuf;

fn main() {
    println!("cargo::rerun-if-env-changed=MUJOCO_DYNAMIC_LINK_DIR");
    let dir = std::env::var_os("MUJOCO_DYNAMIC_LINK_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../.mujoco/lib"));
    let dir = dir.canonicalize().unwrap_or(dir);
    println!("cargo::rustc-link-arg=-Wl,-rpath,{}", dir.display());
}
