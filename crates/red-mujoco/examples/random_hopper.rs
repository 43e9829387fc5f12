//! Random actions in Hopper-v5 (after `bash scripts/setup-mujoco.sh`):
//! returns split into Gymnasium's reward terms.
//! `cargo run --release -p red-mujoco --example random_hopper`.
use rand::{RngExt, SeedableRng};
use red_core::Env;
use red_mujoco::EnvId;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut env = EnvId::Hopper.make()?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    for episode in 0..3 {
        env.reset(Some(episode))?;
        let (mut ret, mut forward, mut steps) = (0.0, 0.0, 0);
        loop {
            let action: Vec<f64> = (0..3).map(|_| rng.random_range(-1.0..1.0)).collect();
            let step = env.step(&action)?;
            ret += step.reward;
            forward += step.info.get("reward_forward").unwrap_or(0.0);
            steps += 1;
            if step.terminated || step.truncated {
                break;
            }
        }
        println!("episode {episode}: {steps} steps, return {ret:.1} (forward {forward:.1})");
    }
    Ok(())
}
