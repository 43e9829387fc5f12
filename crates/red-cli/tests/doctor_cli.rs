//! `red-cli doctor` on this install: every check passes and is reported.

use std::process::Command;

#[test]
fn doctor_reports_every_check() {
    let out = Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args(["doctor", "--steps", "50"])
        .output()
        .expect("red-cli runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "stdout: {stdout}\nstderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("MuJoCo library: 3.17.0"), "{stdout}");
    for env in [
        "Hopper-v5",
        "HalfCheetah-v5",
        "Walker2d-v5",
        "Ant-v5",
        "Reacher-v5",
        "drive",
    ] {
        assert!(
            stdout
                .lines()
                .any(|l| l.contains(env) && l.contains(" ok ")),
            "{env} not reported ok: {stdout}"
        );
    }
    assert!(stdout.contains("everything works"));
}

#[test]
fn doctor_rejects_zero_steps() {
    let out = Command::new(env!("CARGO_BIN_EXE_red-cli"))
        .args(["doctor", "--steps", "0"])
        .output()
        .expect("red-cli runs");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--steps"));
}
