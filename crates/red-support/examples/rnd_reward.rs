//! RED's reward from a demonstration file: fits the release's RND on the
//! expert pairs, calibrates σ1 on them and scores the expert's actions with
//! growing noise. `cargo run --release -p red-support --example rnd_reward
//! [FILE]`. A crate that depends on red-support gets this speed only with
//! optimised dependencies (see the README's "Using the crates").
use ndarray::Array2;
use rand::{RngExt, SeedableRng};
use red_core::Demos;
use red_support::{RedReward, RedRewardConfig, RndConfig, SupportEstimatorConfig, no_progress};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "data/drive-scripted-expert.json".into());
    let demos = Demos::read(path.as_ref())?;
    let (s, a) = demos.pairs();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let start = std::time::Instant::now();
    let model = RndConfig::default().fit(s.view(), a.view(), &mut rng, &mut no_progress)?;
    println!(
        "RND fit on {} pairs: {:.2} s",
        s.nrows(),
        start.elapsed().as_secs_f64()
    );
    let reward = RedReward::new(model, &RedRewardConfig::default(), s.view(), a.view())?;
    for noise in [0.0, 0.03, 0.1, 0.3] {
        let noisy =
            Array2::from_shape_fn(a.dim(), |ij| a[ij] + noise * rng.random_range(-1.0..1.0));
        let r = reward.reward(s.view(), noisy.view())?;
        println!(
            "action noise {noise:>4}: mean reward {:.3}",
            r.mean().unwrap_or(f64::NAN)
        );
    }
    Ok(())
}
