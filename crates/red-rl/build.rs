//! Embeds the folder of the MuJoCo shared library as an rpath of this
//! crate's benches only: the `trpo_hopper` bench runs TRPO on `red-mujoco`'s
//! Hopper (a dev-dependency; the library itself does not use MuJoCo). The
//! folder is `MUJOCO_DYNAMIC_LINK_DIR` (set in `.cargo/config.toml`, filled
//! by `scripts/setup-mujoco.sh`).

use std::path::PathBuf;

fn main() {
    println!("cargo::rerun-if-env-changed=MUJOCO_DYNAMIC_LINK_DIR");
    let dir = std::env::var_os("MUJOCO_DYNAMIC_LINK_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../.mujoco/lib"));
    let dir = dir.canonicalize().unwrap_or(dir);
    println!("cargo::rustc-link-arg-benches=-Wl,-rpath,{}", dir.display());
}
