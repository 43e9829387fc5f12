//! How RED's MuJoCo reward, fitted with a run's defaults on a demonstration
//! file, scores the demo pairs and pairs a learner would produce: the demo
//! states with the actions clipped to the action space, with Gaussian noise
//! as TRPO's policy samples (log-std 0 is sigma 1), with zero actions, and
//! the episodes of a still (zero-action) and of a random (N(0, 1)) policy.
//!
//! `cargo run --release -p red-experiments --example red_reward_probe --
//! FILE... [--seed N] [--stored-actions]` (each file's task is read from the
//! file). The fit is the one `red-cli mujoco train --method red --demo FILE
//! --seed N` makes: same config, same estimator stream. Where the task's
//! RED clips actions for its reward (`RunConfig::reward_clips_actions`,
//! Hopper since session 27), the demo actions are clipped for the fit and
//! every scored action is clipped too, as in the run; `--stored-actions`
//! turns that off (the reward of session 25's probe table). `--config
//! FILE` overlays a run's config file on the task's defaults (as
//! `red-cli mujoco train --config` does); `--pairs FILE` also scores the
//! pairs of another demonstration file of the task (e.g. a learner's
//! episodes written by `red-cli mujoco demos --policy`). Where the config
//! has the time feature (`RunConfig::time_feature`, RED on Reacher since
//! session 51), the demo files and the still and random episodes get it
//! too, as in the run.
use ndarray::{Array1, Array2, ArrayView2};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use red_core::{Env, RewardModel, Seeder, Space, Stream};
use red_experiments::imitation::{Method, fit_reward};
use red_experiments::mujoco::run::{RunConfig, load_run_demos, run_env};
use red_mujoco::EnvId;

type AnyResult<T> = Result<T, Box<dyn std::error::Error>>;

fn main() -> AnyResult<()> {
    let mut files = Vec::new();
    let mut seed = 0u64;
    let mut stored = false;
    let mut config = None;
    let mut extra = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--seed" {
            seed = args.next().ok_or("--seed needs a value")?.parse()?;
        } else if a == "--config" {
            config = Some(args.next().ok_or("--config needs a file")?);
        } else if a == "--pairs" {
            extra.push(args.next().ok_or("--pairs needs a file")?);
        } else if a == "--stored-actions" {
            stored = true;
        } else {
            files.push(a);
        }
    }
    if files.is_empty() {
        return Err(
            "usage: red_reward_probe FILE... [--seed N] [--stored-actions] \
                    [--config FILE] [--pairs FILE]..."
                .into(),
        );
    }
    for f in &files {
        probe(f, seed, stored, config.as_deref(), &extra)?;
    }
    Ok(())
}

fn probe(
    file: &str,
    seed: u64,
    stored: bool,
    config: Option<&str>,
    extra: &[String],
) -> AnyResult<()> {
    let raw = red_core::Demos::read(file.as_ref())?;
    let env_id: EnvId = raw.env_id.parse()?;
    let mut cfg = RunConfig::for_task(env_id, Method::Red);
    if let Some(path) = config {
        cfg = cfg.with_overrides(&std::fs::read_to_string(path)?, path.as_ref())?;
    }
    let demos = load_run_demos(file.as_ref(), &cfg)?;
    let (s, a) = demos.pairs();
    let mut env = run_env(&cfg)?;
    let (low, high) = match env.action_space() {
        Space::Box(b) => (b.low.clone(), b.high.clone()),
        Space::Discrete(_) => return Err("a discrete action space".into()),
    };
    let clip = |x: ArrayView2<'_, f64>| {
        let mut y = x.to_owned();
        for mut row in y.rows_mut() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = v.clamp(low[j], high[j]);
            }
        }
        y
    };

    println!("== {file} ({env_id}, {} pairs)", s.nrows());
    let returns = demos.returns().unwrap_or_default();
    println!("returns: {returns:.1?}");
    let n_out = a
        .rows()
        .into_iter()
        .flat_map(|r| {
            r.iter()
                .enumerate()
                .map(|(j, v)| (*v < low[j] || *v > high[j]) as usize)
                .collect::<Vec<_>>()
        })
        .sum::<usize>();
    println!(
        "action entries outside the box: {:.1}% ({n_out} of {})",
        100.0 * n_out as f64 / a.len() as f64,
        a.len()
    );
    let stds: Vec<f64> = a.columns().into_iter().map(|c| c.std(0.0)).collect();
    let maxabs: Vec<f64> = a
        .columns()
        .into_iter()
        .map(|c| c.iter().fold(0.0f64, |m, v| m.max(v.abs())))
        .collect();
    println!("per-dimension action std: {stds:.3?}; max |a|: {maxabs:.2?}");

    if stored {
        cfg.reward_clips_actions = false;
    }
    let clips = cfg.reward_clips_actions;
    // The pairs the run fits on: as stored, or with the actions clipped.
    let fit_a = if clips { clip(a.view()) } else { a.clone() };
    println!(
        "reward fitted on the actions {}, and scores them so",
        if clips { "clipped" } else { "as stored" }
    );
    // The settings a run fits with: the epochs for this many pairs
    // (`epochs_reference_pairs`) and the context left out if set.
    let context = demos.context_dims();
    let scaled = cfg.reward_fit_config(s.nrows(), &context);
    println!(
        "context dimensions {context:?}; left out of the reward: {:?}",
        scaled.rnd.ignored_state_dims
    );
    let settings = scaled.reward_settings();
    let seeder = Seeder::new(seed);
    let mut rng = seeder.rng(Stream::Estimator);
    let t = std::time::Instant::now();
    let reward = fit_reward(
        Method::Red,
        &settings,
        s.view(),
        fit_a.view(),
        &mut rng,
        seeder.derive(Stream::Estimator),
    )?
    .ok_or("no reward")?;
    let sigma1 = reward.support().map(|r| r.sigma1()).unwrap_or(f64::NAN);
    println!(
        "RED reward fitted in {:.1} s, sigma1 {sigma1:.1}",
        t.elapsed().as_secs_f64()
    );

    let mut noise_rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    let noisy = |x: ArrayView2<'_, f64>, sd: f64, rng: &mut ChaCha8Rng| {
        x.mapv(|v| v + sd * rng.sample::<f64, _>(StandardNormal))
    };
    let zeros = Array2::<f64>::zeros(a.dim());
    let ca = clip(a.view());
    let mut rows: Vec<(String, Array1<f64>)> = Vec::new();
    let mut score =
        |name: &str, st: ArrayView2<'_, f64>, ac: ArrayView2<'_, f64>| -> AnyResult<()> {
            let r = if clips {
                reward.rewards(st, clip(ac).view())?
            } else {
                reward.rewards(st, ac)?
            };
            rows.push((name.to_string(), r));
            Ok(())
        };
    score("demo pairs", s.view(), a.view())?;
    score("demo states, actions clipped", s.view(), ca.view())?;
    for sd in [0.14, 0.37, 1.0] {
        let x = noisy(a.view(), sd, &mut noise_rng);
        score(
            &format!("demo states, actions + N(0, {sd}^2)"),
            s.view(),
            x.view(),
        )?;
        let x = noisy(ca.view(), sd, &mut noise_rng);
        score(
            &format!("demo states, clipped actions + N(0, {sd}^2)"),
            s.view(),
            x.view(),
        )?;
    }
    score("demo states, zero actions", s.view(), zeros.view())?;
    for f in extra {
        let (xs, xa) = load_run_demos(f.as_ref(), &cfg)?.pairs();
        score(&format!("pairs of {f}"), xs.view(), xa.view())?;
    }
    let (ss, sa) = rollouts(&mut env, 5, seed, |_, _| vec![0.0; low.len()])?;
    score(
        &format!("still policy (a = 0), {} steps of 5 episodes", ss.nrows()),
        ss.view(),
        sa.view(),
    )?;
    let mut pol_rng = ChaCha8Rng::seed_from_u64(seed ^ 0xfa11);
    let (rs, ra) = rollouts(&mut env, 5, seed + 100, |_, n| {
        (0..n)
            .map(|_| pol_rng.sample::<f64, _>(StandardNormal))
            .collect()
    })?;
    score(
        &format!("random policy N(0, 1), {} steps of 5 episodes", rs.nrows()),
        rs.view(),
        ra.view(),
    )?;
    let rac = clip(ra.view());
    score(
        "random policy N(0, 1), actions clipped",
        rs.view(),
        rac.view(),
    )?;

    println!("| pairs | mean reward | 10% | median | 90% |\n|---|---|---|---|---|");
    for (name, r) in &rows {
        let mut v = r.to_vec();
        v.sort_by(f64::total_cmp);
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
        println!(
            "| {name} | {:.3} | {:.3} | {:.3} | {:.3} |",
            r.mean().unwrap_or(f64::NAN),
            q(0.1),
            q(0.5),
            q(0.9)
        );
    }
    println!();
    Ok(())
}

/// `episodes` episodes of `act(obs, act_dim)` from resets seeded
/// `seed, seed + 1, ...`; the environment receives the actions clipped, the
/// returned pairs keep them as `act` gave them.
fn rollouts(
    env: &mut impl Env,
    episodes: u64,
    seed: u64,
    mut act: impl FnMut(&[f64], usize) -> Vec<f64>,
) -> AnyResult<(Array2<f64>, Array2<f64>)> {
    let (low, high) = match env.action_space() {
        Space::Box(b) => (b.low.clone(), b.high.clone()),
        Space::Discrete(_) => return Err("a discrete action space".into()),
    };
    let (mut obs_rows, mut act_rows) = (Vec::new(), Vec::new());
    let od = env.observation_space().dim();
    for e in 0..episodes {
        let (mut obs, _) = env.reset(Some(seed + e))?;
        loop {
            let a = act(&obs, low.len());
            let sent: Vec<f64> = a
                .iter()
                .enumerate()
                .map(|(j, v)| v.clamp(low[j], high[j]))
                .collect();
            obs_rows.extend_from_slice(&obs);
            act_rows.extend_from_slice(&a);
            let step = env.step(&sent)?;
            obs = step.observation;
            if step.terminated || step.truncated {
                break;
            }
        }
    }
    let n = obs_rows.len() / od;
    Ok((
        Array2::from_shape_vec((n, od), obs_rows)?,
        Array2::from_shape_vec((n, low.len()), act_rows)?,
    ))
}
