//! Behaviour cloning of a Gaussian policy on a demonstration file's pairs,
//! with the observation normaliser every learner uses:
//! `cargo run --release -p red-rl --example behaviour_cloning [FILE]`.
use rand::SeedableRng;
use red_core::Demos;
use red_rl::bc::{BcConfig, behavior_clone};
use red_rl::normalize::ObsNormalizer;
use red_rl::policy::{GaussianPolicy, GaussianPolicyConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "data/drive-scripted-expert.json".into());
    let demos = Demos::read(path.as_ref())?;
    let (s, a) = demos.pairs();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let mut norm = ObsNormalizer::from_data(s.view(), 5.0, 1e-2)?;
    norm.freeze();
    let config = GaussianPolicyConfig::default();
    let mut policy =
        GaussianPolicy::new(&config, demos.obs_dim, demos.act_dim, Some(norm), &mut rng)?;
    let losses = behavior_clone(
        &mut policy,
        s.view(),
        a.view(),
        &BcConfig::default(),
        &mut rng,
    )?;
    println!(
        "BC on {} pairs: loss {:.4} -> {:.4}",
        s.nrows(),
        losses.first().copied().unwrap_or(f64::NAN),
        losses.last().copied().unwrap_or(f64::NAN)
    );
    let first = &demos.trajectories[0];
    println!(
        "first state: expert {:?}, policy {:?}",
        first.actions[0],
        policy.act_deterministic(&first.observations[0])?
    );
    Ok(())
}
