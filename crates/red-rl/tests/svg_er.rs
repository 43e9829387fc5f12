//! SVG(1)-ER: the policy gradient through model and reward against finite
//! differences, learning on a small reaching task, determinism.

use std::ops::ControlFlow;

use ndarray::{Array1, Array2, ArrayView2};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use red_core::{BoxSpace, Env, Info, Space, Step};
use red_rl::episodic::{EpisodeHooks, EpisodicLearner};
use red_rl::policy::{GaussianPolicy, GaussianPolicyConfig};
use red_rl::svg::{DifferentiableReward, EpisodeOutcome, Svg1, SvgConfig};

/// Target point of the reaching task.
pub const TARGET: [f64; 2] = [0.5, -0.3];
/// Move per unit action.
pub const SPEED: f64 = 0.1;
/// Episode length.
pub const HORIZON: usize = 20;

/// A point in the plane moved by `SPEED * clip(a)`; the observation is its
/// position, the episode lasts `HORIZON` steps.
pub struct Reach {
    pos: [f64; 2],
    t: usize,
    rng: ChaCha8Rng,
    obs_space: Space,
    act_space: Space,
}

impl Default for Reach {
    fn default() -> Self {
        Self {
            pos: [0.0; 2],
            t: 0,
            rng: ChaCha8Rng::seed_from_u64(0),
            obs_space: Space::Box(BoxSpace::uniform(2, -3.0, 3.0)),
            act_space: Space::Box(BoxSpace::uniform(2, -1.0, 1.0)),
        }
    }
}

/// The reward of moving from `s` by `a`: minus the squared distance to the
/// target after the move (unclipped, so it is differentiable everywhere).
pub fn reach_reward(s: &[f64], a: &[f64]) -> f64 {
    -(0..2)
        .map(|j| (s[j] + SPEED * a[j] - TARGET[j]).powi(2))
        .sum::<f64>()
}

impl Env for Reach {
    fn observation_space(&self) -> &Space {
        &self.obs_space
    }
    fn action_space(&self) -> &Space {
        &self.act_space
    }
    fn reset(&mut self, seed: Option<u64>) -> red_core::Result<(Vec<f64>, Info)> {
        if let Some(s) = seed {
            self.rng = ChaCha8Rng::seed_from_u64(s);
        }
        self.pos = [
            self.rng.random_range(-1.0..1.0),
            self.rng.random_range(-1.0..1.0),
        ];
        self.t = 0;
        Ok((self.pos.to_vec(), Info::new()))
    }
    fn step(&mut self, action: &[f64]) -> red_core::Result<Step> {
        let a: Vec<f64> = action.iter().map(|v| v.clamp(-1.0, 1.0)).collect();
        let reward = reach_reward(&self.pos, &a);
        for (p, a) in self.pos.iter_mut().zip(&a) {
            *p += SPEED * a;
        }
        self.t += 1;
        let mut info = Info::new();
        info.set("distance", (-reach_reward(&self.pos, &[0.0, 0.0])).sqrt());
        Ok(Step {
            observation: self.pos.to_vec(),
            reward,
            terminated: false,
            truncated: self.t >= HORIZON,
            info,
        })
    }
}

/// [`reach_reward`] with its action gradient.
pub struct ReachReward;

impl DifferentiableReward for ReachReward {
    fn reward_and_grad(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<(Array1<f64>, Array2<f64>)> {
        let n = states.nrows();
        let mut r = Array1::zeros(n);
        let mut g = Array2::zeros((n, 2));
        for i in 0..n {
            let s = [states[[i, 0]], states[[i, 1]]];
            let a = [actions[[i, 0]], actions[[i, 1]]];
            r[i] = reach_reward(&s, &a);
            for j in 0..2 {
                g[[i, j]] = -2.0 * SPEED * (s[j] + SPEED * a[j] - TARGET[j]);
            }
        }
        Ok((r, g))
    }
}

/// Mean final distance to the target of the deterministic policy over
/// `episodes` fixed starts.
pub fn eval_distance(policy: &red_rl::policy::GaussianPolicy, episodes: u64) -> f64 {
    let mut env = Reach::default();
    let mut total = 0.0;
    for e in 0..episodes {
        let (mut obs, _) = env.reset(Some(1_000 + e)).unwrap();
        let mut last = 0.0;
        for _ in 0..HORIZON {
            let a = policy.act_deterministic(&obs).unwrap();
            let st = env.step(&a).unwrap();
            last = st.info.get("distance").unwrap();
            obs = st.observation;
        }
        total += last;
    }
    total / episodes as f64
}

fn fresh(seed: u64, config: &SvgConfig) -> (Svg1, ChaCha8Rng) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let pc = GaussianPolicyConfig {
        hidden: vec![16],
        init_log_std: -0.5,
        ..GaussianPolicyConfig::default()
    };
    let policy = GaussianPolicy::new(&pc, 2, 2, None, &mut rng).unwrap();
    let svg = Svg1::new(config, policy, &mut rng).unwrap();
    (svg, rng)
}

/// `steps` of training on Reach with no hooks.
fn train_plain(svg: &mut Svg1, steps: u64, rng: &mut ChaCha8Rng) {
    let mut env = Reach::default();
    svg.train(
        &mut env,
        &ReachReward,
        steps,
        None,
        &|_, _| 0.0,
        rng,
        &mut |_| {},
    )
    .unwrap();
}

#[test]
fn policy_gradient_matches_finite_differences() {
    let config = SvgConfig {
        hidden: vec![8],
        gamma: 0.9,
        learning_starts: 0,
        ..SvgConfig::default()
    };
    let (mut svg, mut rng) = fresh(3, &config);
    // Some data, and a few model/value steps so both are non-trivial.
    train_plain(&mut svg, 60, &mut rng);
    let batch = svg.sample(16, &mut rng).unwrap();
    let inputs = svg.policy_inputs(&batch).unwrap();
    // At the current parameters the inferred noise reproduces the actions.
    let (obj, _) = svg.policy_objective(&batch, &inputs, &ReachReward).unwrap();
    assert!(obj.is_finite());
    // A random direction; compare the directional derivative.
    let analytic = check_policy_gradient(&svg, &batch, &inputs, &mut rng);
    // And the gradient is not trivially zero.
    assert!(analytic.abs() > 1e-4, "analytic {analytic}");
    svg.update_policy(&batch, &inputs, &ReachReward).unwrap();
}

fn learner_set(svg: &mut Svg1, params: &[f32]) {
    svg.policy_mut().net_mut().set_params_flat(params).unwrap();
}

/// The policy step's gradient along a random direction against central
/// finite differences of the objective (step 1e-2, 2% tolerance); returns
/// the analytic directional derivative.
fn check_policy_gradient(
    svg: &Svg1,
    batch: &red_rl::svg::SvgBatch,
    inputs: &red_rl::svg::PolicyInputs,
    rng: &mut ChaCha8Rng,
) -> f64 {
    let (_, grads) = svg.policy_objective(batch, inputs, &ReachReward).unwrap();
    let g = grads.flat();
    let dir: Vec<f32> = (0..g.len())
        .map(|_| rng.random_range(-1.0f32..1.0))
        .collect();
    let analytic: f64 = g.iter().zip(&dir).map(|(a, b)| *a as f64 * *b as f64).sum();
    let p0 = svg.policy().net().params_flat();
    let h = 1e-2f32;
    let at = |sign: f32| {
        let mut learner = svg.clone();
        let p: Vec<f32> = p0.iter().zip(&dir).map(|(p, d)| p + sign * h * d).collect();
        learner_set(&mut learner, &p);
        learner
            .policy_objective(batch, inputs, &ReachReward)
            .unwrap()
            .0
    };
    let numeric = (at(1.0) - at(-1.0)) / (2.0 * h as f64);
    assert!(
        (numeric - analytic).abs() <= 0.02 * analytic.abs().max(1e-3) + 1e-5,
        "analytic {analytic}, numeric {numeric}"
    );
    analytic
}

/// The settings of the reaching tests.
fn reach_config() -> SvgConfig {
    SvgConfig {
        hidden: vec![32],
        gamma: 0.9,
        policy_lr: 3e-3,
        learning_starts: 200,
        policy_delay: 200,
        batch_size: 32,
        ..SvgConfig::default()
    }
}

fn run(seed: u64, steps: u64) -> (Svg1, Vec<f64>) {
    run_with(&reach_config(), seed, steps)
}

fn run_with(config: &SvgConfig, seed: u64, steps: u64) -> (Svg1, Vec<f64>) {
    let (mut svg, mut rng) = fresh(seed, config);
    let mut env = Reach::default();
    let mut returns = Vec::new();
    svg.train(
        &mut env,
        &ReachReward,
        steps,
        None,
        &|_, _| 0.0,
        &mut rng,
        &mut |e| returns.push(e.true_return),
    )
    .unwrap();
    (svg, returns)
}

#[test]
fn learns_to_reach_the_target() {
    let (svg0, _) = fresh(5, &SvgConfig::default());
    let before = eval_distance(svg0.policy(), 10);
    let (svg, returns) = run(5, 8_000);
    let after = eval_distance(svg.policy(), 10);
    eprintln!("final distance {before} -> {after}");
    assert_eq!(returns.len(), 8_000 / HORIZON);
    assert!(
        after < 0.2 && after < 0.4 * before,
        "final distance {before} -> {after}"
    );
}

#[test]
fn same_seed_same_result() {
    let (a, ra) = run(9, 600);
    let (b, rb) = run(9, 600);
    assert_eq!(ra, rb);
    assert_eq!(a.policy(), b.policy());
    let (c, _) = run(10, 600);
    assert_ne!(a.policy(), c.policy());
}

#[test]
fn config_validation_names_the_field() {
    for (config, field) in [
        (
            SvgConfig {
                bc_weight: -1.0,
                ..SvgConfig::default()
            },
            "bc_weight",
        ),
        (
            SvgConfig {
                bc_weight: f64::NAN,
                ..SvgConfig::default()
            },
            "bc_weight",
        ),
        (
            SvgConfig {
                gamma: 1.0,
                ..SvgConfig::default()
            },
            "gamma",
        ),
        (
            SvgConfig {
                iw_clip: 0.5,
                ..SvgConfig::default()
            },
            "iw_clip",
        ),
        (
            SvgConfig {
                batch_size: 0,
                ..SvgConfig::default()
            },
            "batch_size",
        ),
        (
            SvgConfig {
                target_tau: 0.0,
                ..SvgConfig::default()
            },
            "target_tau",
        ),
        (
            SvgConfig {
                sil_weight: -0.5,
                ..SvgConfig::default()
            },
            "sil_weight",
        ),
        (
            SvgConfig {
                sil_weight: 1.0,
                sil_episodes: 0,
                ..SvgConfig::default()
            },
            "sil_episodes",
        ),
        (
            SvgConfig {
                value_nstep: 0,
                ..SvgConfig::default()
            },
            "value_nstep",
        ),
        (
            SvgConfig {
                eta_scale: 1.5,
                ..SvgConfig::default()
            },
            "eta_scale",
        ),
        (
            SvgConfig {
                eta_scale: f64::NAN,
                ..SvgConfig::default()
            },
            "eta_scale",
        ),
    ] {
        let e = config.validate().unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    }
    let json = serde_json::to_string(&SvgConfig::default()).unwrap();
    let back: SvgConfig = serde_json::from_str(&json).unwrap();
    assert_eq!(back, SvgConfig::default());
    assert!(serde_json::from_str::<SvgConfig>(r#"{"gama": 0.9}"#).is_err());
}

/// A reward that turns NaN after `after` calls on single pairs.
struct BrokenReward {
    after: std::cell::Cell<usize>,
}

impl DifferentiableReward for BrokenReward {
    fn reward_and_grad(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> red_core::Result<(Array1<f64>, Array2<f64>)> {
        let (mut r, g) = ReachReward.reward_and_grad(states, actions)?;
        if states.nrows() == 1 {
            let left = self.after.get();
            if left == 0 {
                r[0] = f64::NAN;
            } else {
                self.after.set(left - 1);
            }
        }
        Ok((r, g))
    }
}

/// [`Reach`] whose observation turns NaN at step `at` of an episode.
struct NanReach {
    inner: Reach,
    at: usize,
}

impl Env for NanReach {
    fn observation_space(&self) -> &Space {
        self.inner.observation_space()
    }
    fn action_space(&self) -> &Space {
        self.inner.action_space()
    }
    fn reset(&mut self, seed: Option<u64>) -> red_core::Result<(Vec<f64>, Info)> {
        self.inner.reset(seed)
    }
    fn step(&mut self, action: &[f64]) -> red_core::Result<Step> {
        let mut st = self.inner.step(action)?;
        if self.inner.t == self.at {
            st.observation[1] = f64::NAN;
        }
        Ok(st)
    }
}

#[test]
fn non_finite_reward_or_observation_stops_with_what_and_step() {
    let (mut svg, mut rng) = fresh(1, &SvgConfig::default());
    let reward = BrokenReward {
        after: std::cell::Cell::new(7),
    };
    let e = svg
        .train(
            &mut Reach::default(),
            &reward,
            100,
            None,
            &|_, _| 0.0,
            &mut rng,
            &mut |_| {},
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("imitation reward") && e.contains('7'), "{e}");

    let (mut svg, mut rng) = fresh(1, &SvgConfig::default());
    let mut env = NanReach {
        inner: Reach::default(),
        at: 5,
    };
    let e = svg
        .train(
            &mut env,
            &ReachReward,
            100,
            None,
            &|_, _| 0.0,
            &mut rng,
            &mut |_| {},
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("observation") && e.contains('4'), "{e}");
}

/// Small networks and short warm-ups, for tests of the training loop.
fn small_config() -> SvgConfig {
    SvgConfig {
        hidden: vec![16],
        learning_starts: 50,
        policy_delay: 50,
        batch_size: 16,
        ..SvgConfig::default()
    }
}

#[test]
fn serialised_learner_continues_identically() {
    let config = small_config();
    let (mut a, mut rng_a) = fresh(2, &config);
    let mut env = Reach::default();
    a.train(
        &mut env,
        &ReachReward,
        200,
        None,
        &|_, _| 0.0,
        &mut rng_a,
        &mut |_| {},
    )
    .unwrap();
    let saved = serde_json::to_string(&(&a, &rng_a)).unwrap();
    let (mut b, mut rng_b): (Svg1, ChaCha8Rng) = serde_json::from_str(&saved).unwrap();
    let mut ra = Vec::new();
    let mut rb = Vec::new();
    a.train(
        &mut env,
        &ReachReward,
        200,
        None,
        &|_, _| 0.0,
        &mut rng_a,
        &mut |e| ra.push(e.true_return),
    )
    .unwrap();
    b.train(
        &mut Reach::default(),
        &ReachReward,
        200,
        None,
        &|_, _| 0.0,
        &mut rng_b,
        &mut |e| rb.push(e.true_return),
    )
    .unwrap();
    assert_eq!(ra, rb);
    assert_eq!(a.policy(), b.policy());
    assert_eq!(a.env_steps(), b.env_steps());
}

/// Hooks that record every finished episode's return and, after
/// `stop_after` episodes, save the learner with its random stream and stop.
struct SaveAndStop {
    stop_after: usize,
    returns: Vec<f64>,
    saved: Option<String>,
}

impl EpisodeHooks<Svg1, ChaCha8Rng> for SaveAndStop {
    type Error = red_rl::Error;

    fn reward(&self) -> &dyn DifferentiableReward {
        &ReachReward
    }

    fn after_episode(
        &mut self,
        svg: &Svg1,
        rng: &ChaCha8Rng,
        ep: &EpisodeOutcome,
    ) -> red_rl::Result<ControlFlow<()>> {
        if ep.finished {
            self.returns.push(ep.report.true_return);
        }
        if self.returns.len() == self.stop_after {
            self.saved = Some(serde_json::to_string(&(svg, rng)).unwrap());
            return Ok(ControlFlow::Break(()));
        }
        Ok(ControlFlow::Continue(()))
    }
}

#[test]
fn hooks_stop_and_checkpoint_and_the_resumed_loop_ends_with_the_same_numbers() {
    let config = small_config();
    let hooks = |stop_after| SaveAndStop {
        stop_after,
        returns: Vec::new(),
        saved: None,
    };
    let train = |svg: &mut Svg1, rng: &mut ChaCha8Rng, hooks: &mut SaveAndStop| {
        let flow = svg.train_with(&mut Reach::default(), 400, None, &|_, _| 0.0, rng, hooks);
        flow.unwrap()
    };
    let (mut whole, mut rng) = fresh(4, &config);
    let mut all = hooks(0);
    assert_eq!(
        train(&mut whole, &mut rng, &mut all),
        ControlFlow::Continue(())
    );
    assert_eq!(whole.env_steps(), 400);

    let (mut cut, mut rng) = fresh(4, &config);
    let mut first = hooks(3);
    assert_eq!(
        train(&mut cut, &mut rng, &mut first),
        ControlFlow::Break(())
    );
    assert!(cut.env_steps() < 400);
    let (mut resumed, mut rng): (Svg1, ChaCha8Rng) =
        serde_json::from_str(first.saved.as_deref().unwrap()).unwrap();
    let mut rest = hooks(0);
    let flow = train(&mut resumed, &mut rng, &mut rest);
    assert_eq!(flow, ControlFlow::Continue(()));
    first.returns.extend(rest.returns);
    assert_eq!(first.returns, all.returns);
    assert_eq!(resumed.policy(), whole.policy());
}

#[test]
fn fixed_std_sets_exploration_and_keeps_the_gradient_exact() {
    let config = SvgConfig {
        hidden: vec![8],
        gamma: 0.9,
        learning_starts: 0,
        fixed_std: Some(0.2),
        ..SvgConfig::default()
    };
    // The policy's own sigma is exp(-0.5) ~ 0.61; acting must use 0.2.
    let (mut svg, mut rng) = fresh(3, &config);
    let obs = [0.1, -0.2];
    let mean = svg.policy().act_deterministic(&obs).unwrap();
    let n = 4000;
    let mut var = 0.0;
    for _ in 0..n {
        let (a, _) = svg.act(&obs, &mut rng).unwrap();
        var += (a[0] - mean[0]).powi(2) / n as f64;
    }
    assert!((var.sqrt() - 0.2).abs() < 0.02, "std {}", var.sqrt());
    train_plain(&mut svg, 60, &mut rng);
    let batch = svg.sample(16, &mut rng).unwrap();
    let inputs = svg.policy_inputs(&batch).unwrap();
    check_policy_gradient(&svg, &batch, &inputs, &mut rng);
}

#[test]
fn scheduled_fixed_std_and_averaged_policy_learn_to_reach() {
    let config = SvgConfig {
        hidden: vec![32],
        gamma: 0.9,
        policy_lr: 3e-3,
        learning_starts: 200,
        policy_delay: 200,
        batch_size: 32,
        fixed_std: Some(0.5),
        fixed_std_final: Some(0.2),
        policy_lr_final: Some(1e-3),
        schedule_steps: 6_000,
        policy_avg_tau: 0.01,
        ..SvgConfig::default()
    };
    let (mut svg, mut rng) = fresh(5, &config);
    let before = eval_distance(svg.policy(), 10);
    let mut env = Reach::default();
    svg.train(
        &mut env,
        &ReachReward,
        8_000,
        None,
        &|_, _| 0.0,
        &mut rng,
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(svg.current_fixed_std(), Some(0.2));
    assert_ne!(svg.reported_policy(), svg.policy());
    let after = eval_distance(svg.reported_policy(), 10);
    assert!(
        after < 0.2 && after < 0.4 * before,
        "final distance {before} -> {after}"
    );
}

#[test]
fn the_bc_term_needs_fitting_demonstration_pairs() {
    let config = SvgConfig {
        bc_weight: 3.0,
        ..small_config()
    };
    let (mut svg, mut rng) = fresh(0, &config);
    for (s, a) in [
        (Array2::zeros((0, 2)), Array2::zeros((0, 2))),
        (Array2::zeros((5, 2)), Array2::zeros((4, 2))),
        (Array2::zeros((5, 3)), Array2::zeros((5, 2))),
        (Array2::zeros((5, 2)), Array2::zeros((5, 1))),
    ] {
        let e = svg.set_demos(s, a).unwrap_err().to_string();
        assert!(e.contains("demonstration pairs"), "{e}");
    }
    let mut bad = Array2::zeros((5, 2));
    bad[[2, 1]] = f64::NAN;
    assert!(svg.set_demos(bad, Array2::zeros((5, 2))).is_err());
    // Without pairs the term cannot be computed: an error, not a silent skip.
    let e = svg
        .train(
            &mut Reach::default(),
            &ReachReward,
            200,
            None,
            &|_, _| 0.0,
            &mut rng,
            &mut |_| {},
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("bc_weight") && e.contains("set_demos"), "{e}");
    let (mut svg, mut rng) = fresh(0, &config);
    svg.set_demos(Array2::zeros((5, 2)), Array2::zeros((5, 2)))
        .unwrap();
    svg.train(
        &mut Reach::default(),
        &ReachReward,
        200,
        None,
        &|_, _| 0.0,
        &mut rng,
        &mut |_| {},
    )
    .unwrap();
}

/// The self-imitation term keeps the episodes of highest own return (the
/// learning reward plus the terminal adjustment), highest first, and
/// changes training; with weight 0 it keeps nothing.
#[test]
fn self_imitation_keeps_the_best_own_returns() {
    let train = |sil_weight: f64| {
        let config = SvgConfig {
            sil_weight,
            sil_episodes: 3,
            ..small_config()
        };
        let (mut svg, mut rng) = fresh(4, &config);
        let mut env = Reach::default();
        let mut own = Vec::new();
        // A terminal adjustment that depends on the last reward, so the kept
        // returns must include it to match.
        let terminal = |r: f64, _: &red_core::Info| if r < -0.3 { -1.0 } else { 0.0 };
        svg.train(
            &mut env,
            &ReachReward,
            400,
            None,
            &terminal,
            &mut rng,
            &mut |e| own.push(e.imitation_return),
        )
        .unwrap();
        (svg, own)
    };
    let (svg, own) = train(2.0);
    let mut best = own.clone();
    best.sort_by(|a, b| b.total_cmp(a));
    best.truncate(3);
    assert_eq!(own.len(), 400 / HORIZON);
    assert_eq!(svg.sil_returns(), best);
    let (off, own_off) = train(0.0);
    assert!(off.sil_returns().is_empty());
    assert_ne!(svg.policy(), off.policy(), "the term changed nothing");
    assert_eq!(
        own[..5],
        own_off[..5],
        "episodes before the policy moves differ"
    );
}

#[test]
fn uniform_average_is_the_mean_of_the_policies_since_its_start() {
    let config = SvgConfig {
        policy_avg_tau: 0.3,
        policy_avg_uniform_from: Some(50),
        ..small_config()
    };
    let (mut svg, mut rng) = fresh(4, &config);
    // 60 steps: replay for the updates below, and no policy update yet
    // (updates start after learning_starts + policy_delay = 100 steps).
    train_plain(&mut svg, 60, &mut rng);
    // The exponential average of tau 0.3 is over: the copy is reported but
    // still the start's policy.
    assert_eq!(svg.reported_policy(), svg.policy());
    let mut sum = vec![0.0f64; svg.policy().net().params_flat().len()];
    let updates = 7;
    for _ in 0..updates {
        svg.update(&ReachReward, true, &mut rng).unwrap();
        for (s, p) in sum.iter_mut().zip(svg.policy().net().params_flat()) {
            *s += p as f64;
        }
    }
    assert_ne!(svg.reported_policy(), svg.policy());
    let avg = svg.reported_policy().net().params_flat();
    for (a, s) in avg.iter().zip(&sum) {
        let mean = s / updates as f64;
        assert!(
            (*a as f64 - mean).abs() <= 1e-5 * (1.0 + mean.abs()),
            "{a} vs {mean}"
        );
    }
    // Without a uniform start and with tau 0, there is no averaged copy.
    let (svg, _) = fresh(4, &small_config());
    assert_eq!(svg.reported_policy(), svg.policy());
}

/// An n-step update given a one-step tail is the TD(0) update, number for
/// number; a 5-step target still learns the task while taking another
/// path; the default (1) is not written to configs.
#[test]
fn n_step_value_targets_learn_and_one_step_is_td0() {
    let (mut a, mut rng) = fresh(4, &small_config());
    train_plain(&mut a, 120, &mut rng);
    let mut b = a.clone();
    let batch = a.sample(16, &mut rng).unwrap();
    let w = a.importance_weights(&batch).unwrap();
    let gamma = a.config().gamma;
    let tail = red_rl::replay::NStepTail {
        later_rewards: vec![0.0; 16],
        boot_states: batch.next_states.clone(),
        discount: batch
            .terminated
            .iter()
            .map(|&t| if t { 0.0 } else { gamma })
            .collect(),
    };
    let la = a.update_value(&batch, &w).unwrap();
    let lb = b.update_value_nstep(&batch, &tail, &w).unwrap();
    assert_eq!(la, lb);
    assert_eq!(
        serde_json::to_string(&a).unwrap(),
        serde_json::to_string(&b).unwrap()
    );
    let written = serde_json::to_value(small_config()).unwrap();
    assert_eq!(
        written["value_nstep"], 1,
        "TD(0) is written out, so a saved config laid over other defaults keeps it"
    );
    let mut old = written.clone();
    old.as_object_mut().unwrap().remove("value_nstep");
    let read: SvgConfig = serde_json::from_value(old).unwrap();
    assert_eq!(
        read.value_nstep, 1,
        "a file without the field reads as TD(0)"
    );

    let config = SvgConfig {
        value_nstep: 5,
        ..reach_config()
    };
    let (svg0, _) = fresh(5, &config);
    let before = eval_distance(svg0.policy(), 10);
    let (svg, _) = run_with(&config, 5, 8_000);
    let after = eval_distance(svg.policy(), 10);
    assert_ne!(
        run_with(&config, 5, 600).0.policy(),
        run(5, 600).0.policy(),
        "the 5-step target changes the run"
    );
    eprintln!("5-step: final distance {before} -> {after}");
    assert!(
        after < 0.2 && after < 0.4 * before,
        "final distance {before} -> {after}"
    );
}

/// After 60 training steps: 16 replayed non-terminal rows, the policy,
/// its mean actions on them, and policy-step inputs of zero noise and unit
/// weights.
fn at_the_mean(
    svg: &mut Svg1,
    rng: &mut ChaCha8Rng,
) -> (
    red_rl::svg::SvgBatch,
    GaussianPolicy,
    Array2<f64>,
    red_rl::svg::PolicyInputs,
) {
    train_plain(svg, 60, rng);
    let mut batch = svg.sample(16, rng).unwrap();
    batch.terminated = vec![false; 16];
    let policy = svg.policy().clone();
    let mu = Array2::from_shape_fn((16, 2), |(i, j)| {
        policy
            .act_deterministic(&batch.states.row(i).to_vec())
            .unwrap()[j]
    });
    let inputs = red_rl::svg::PolicyInputs {
        eta: Array2::zeros((16, 2)),
        xi: Array2::zeros((16, 2)),
        weights: vec![1.0; 16],
    };
    (batch, policy, mu, inputs)
}

#[test]
fn lookahead_scores_are_the_policy_objective_at_zero_noise() {
    let config = SvgConfig {
        hidden: vec![8],
        gamma: 0.9,
        learning_starts: 0,
        ..SvgConfig::default()
    };
    let (mut svg, mut rng) = fresh(5, &config);
    let (batch, policy, mu, inputs) = at_the_mean(&mut svg, &mut rng);
    let (obj, _) = svg.policy_objective(&batch, &inputs, &ReachReward).unwrap();
    let with_r = svg
        .lookahead_scores(
            &policy,
            batch.states.view(),
            mu.view(),
            Some(&ReachReward),
            1,
        )
        .unwrap();
    let mean = with_r.iter().sum::<f64>() / 16.0;
    assert!((mean - obj).abs() < 1e-5, "{mean} against {obj}");
    // Without the reward: gamma V(x'), the same rows less their rewards.
    let without = svg
        .lookahead_scores(&policy, batch.states.view(), mu.view(), None, 1)
        .unwrap();
    for (i, (w, v)) in with_r.iter().zip(&without).enumerate() {
        let r = reach_reward(&batch.states.row(i).to_vec(), &mu.row(i).to_vec());
        assert!((w - v - r).abs() < 1e-9, "row {i}: {w} - {v} != {r}");
    }
    // A longer horizon reads the value further on: a different number.
    let h3 = svg
        .lookahead_scores(&policy, batch.states.view(), mu.view(), None, 3)
        .unwrap();
    assert!(h3.iter().zip(&without).any(|(a, b)| (a - b).abs() > 1e-6));
    assert!(
        svg.lookahead_scores(&policy, batch.states.view(), mu.view(), None, 0)
            .is_err()
    );
    // Without the replay the networks, and so the scores, are the same.
    let small = svg.without_replay().unwrap();
    assert_eq!(small.replay_len(), 0);
    let again = small
        .lookahead_scores(
            &policy,
            batch.states.view(),
            mu.view(),
            Some(&ReachReward),
            1,
        )
        .unwrap();
    assert_eq!(again, with_r);
}

/// `eta_scale` scales the inferred policy noise and nothing else: at 0 the
/// policy step's objective is SVG(1)-ER's with `eta` set to 0 (the
/// policy's mean, the same model noise and weights), at 0.5 the noise is
/// half of SVG(1)-ER's, and the setting is written only when it is not 1.
#[test]
fn eta_scale_moves_the_policy_step_toward_the_mean_action() {
    let at = |scale: f64| {
        let config = SvgConfig {
            hidden: vec![8],
            gamma: 0.9,
            learning_starts: 0,
            eta_scale: scale,
            ..SvgConfig::default()
        };
        // No policy step within 60 steps (policy_delay 500): the three
        // learners are the same but for the setting.
        let (mut svg, mut rng) = fresh(9, &config);
        train_plain(&mut svg, 60, &mut rng);
        let mut batch = svg.sample(16, &mut rng).unwrap();
        batch.terminated = vec![false; 16];
        let inputs = svg.policy_inputs(&batch).unwrap();
        (svg, batch, inputs)
    };
    let (full, batch, one) = at(1.0);
    let (_, _, half) = at(0.5);
    let (zero_learner, _, zero) = at(0.0);
    assert!(one.eta.iter().any(|e| e.abs() > 0.1), "{:?}", one.eta);
    for (h, o) in half.eta.iter().zip(&one.eta) {
        assert!((h - 0.5 * o).abs() < 1e-9, "{h} against half of {o}");
    }
    assert!(zero.eta.iter().all(|e| *e == 0.0));
    assert_eq!(zero.xi, one.xi);
    assert_eq!(zero.weights, one.weights);
    // At 0 the objective is r(s, mu) + gamma V(x + f(x, mu) + xi): with
    // the model noise and weights of the replayed actions, the same as
    // SVG(1)-ER's objective with eta set to 0 by hand.
    let by_hand = red_rl::svg::PolicyInputs {
        eta: Array2::zeros(one.eta.dim()),
        ..one.clone()
    };
    let (o0, g0) = zero_learner
        .policy_objective(&batch, &zero, &ReachReward)
        .unwrap();
    let (oh, gh) = full
        .policy_objective(&batch, &by_hand, &ReachReward)
        .unwrap();
    assert!((o0 - oh).abs() < 1e-12, "{o0} against {oh}");
    assert_eq!(g0.flat(), gh.flat());
    let (o1, _) = full.policy_objective(&batch, &one, &ReachReward).unwrap();
    assert!((o1 - o0).abs() > 1e-6, "the replayed actions score {o1}");
    let written = |scale: f64| {
        serde_json::to_string(&SvgConfig {
            eta_scale: scale,
            ..SvgConfig::default()
        })
        .unwrap()
    };
    assert!(!written(1.0).contains("eta_scale"));
    let back: SvgConfig = serde_json::from_str(&written(0.25)).unwrap();
    assert_eq!(back.eta_scale, 0.25);
}

/// The temporal smoothness term pulls the mean actions of consecutive
/// states together: after repeated policy updates on one replayed batch,
/// `mean ||mu(s) - mu(s')||^2` is far smaller with the term than without,
/// and a negative weight is refused.
#[test]
fn the_smoothness_term_brings_consecutive_actions_together() {
    let jump = |svg: &Svg1, b: &red_rl::svg::SvgBatch| {
        let mut total = 0.0;
        for i in 0..b.states.nrows() {
            let a = svg
                .policy()
                .act_deterministic(&b.states.row(i).to_vec())
                .unwrap();
            let a2 = svg
                .policy()
                .act_deterministic(&b.next_states.row(i).to_vec())
                .unwrap();
            total += a.iter().zip(&a2).map(|(u, v)| (u - v).powi(2)).sum::<f64>();
        }
        total / b.states.nrows() as f64
    };
    let run = |smooth_weight: f64| {
        let config = SvgConfig {
            smooth_weight,
            policy_lr: 1e-2,
            ..small_config()
        };
        let (mut svg, mut rng) = fresh(6, &config);
        // Replay without any policy update (updates start at step 100).
        train_plain(&mut svg, 90, &mut rng);
        let b = svg.sample(64, &mut rng).unwrap();
        let before = jump(&svg, &b);
        for _ in 0..30 {
            let inputs = svg.policy_inputs(&b).unwrap();
            svg.update_policy(&b, &inputs, &ReachReward).unwrap();
        }
        (before, jump(&svg, &b))
    };
    let (before, plain) = run(0.0);
    let (before_s, smooth) = run(100.0);
    assert_eq!(before, before_s, "the same start");
    // The fresh policy is nearly constant; the updates without the term
    // make its actions jump between consecutive states, with it far less.
    assert!(
        plain > 10.0 * before && smooth < 0.05 * plain,
        "jump {before} -> {plain} without the term, {smooth} with it"
    );
    let bad = SvgConfig {
        smooth_weight: -1.0,
        ..small_config()
    };
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("smooth_weight"), "{e}");
}

/// The spatial smoothness term makes the mean action move less between
/// nearby states: after the same updates, `mean ||mu(s) - mu(s + d)||^2`
/// over replayed states moved by small fixed offsets `d` is far smaller
/// with the term than without; it is off by default and then not written;
/// negative settings are refused.
#[test]
fn the_spatial_smoothness_term_flattens_the_policy_around_its_states() {
    use rand::{RngExt, SeedableRng};
    let spread = |svg: &Svg1, b: &red_rl::svg::SvgBatch| {
        let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut total = 0.0;
        for i in 0..b.states.nrows() {
            let s = b.states.row(i).to_vec();
            let near: Vec<f64> = s.iter().map(|v| v + r.random_range(-0.1..0.1)).collect();
            let a = svg.policy().act_deterministic(&s).unwrap();
            let a2 = svg.policy().act_deterministic(&near).unwrap();
            total += a.iter().zip(&a2).map(|(u, v)| (u - v).powi(2)).sum::<f64>();
        }
        total / b.states.nrows() as f64
    };
    let run = |spatial_smooth_weight: f64| {
        let config = SvgConfig {
            spatial_smooth_weight,
            spatial_smooth_std: 0.1,
            policy_lr: 1e-2,
            ..small_config()
        };
        let (mut svg, mut rng) = fresh(6, &config);
        train_plain(&mut svg, 90, &mut rng);
        let b = svg.sample(64, &mut rng).unwrap();
        for _ in 0..60 {
            svg.update(&ReachReward, true, &mut rng).unwrap();
        }
        (
            spread(&svg, &b),
            svg.policy()
                .act_deterministic(&b.states.row(0).to_vec())
                .unwrap(),
        )
    };
    let (plain, _) = run(0.0);
    let (smooth, _) = run(100.0);
    assert!(
        smooth < 0.2 * plain,
        "spread {plain} without the term, {smooth} with it"
    );
    // Off by default, and its noise setting is not written while it is
    // the default (files of runs without the term read in builds before
    // it).
    assert_eq!(small_config().spatial_smooth_weight, 0.0);
    let text = serde_json::to_string(&small_config()).unwrap();
    assert!(!text.contains("spatial_smooth"), "{text}");
    for (w, sd, field) in [
        (-1.0, 0.1, "spatial_smooth_weight"),
        (1.0, f64::NAN, "spatial_smooth_std"),
    ] {
        let bad = SvgConfig {
            spatial_smooth_weight: w,
            spatial_smooth_std: sd,
            ..small_config()
        };
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    }
}

/// `twin_value`: a second value network whose smaller reading is used.
/// The policy step's gradient (through whichever network is smaller,
/// row by row) matches finite differences, the lookahead reads the same
/// smaller value as the policy step, the learner still learns to reach,
/// a saved learner continues identically, and the setting and the second
/// network are written only when on.
#[test]
fn twin_value_reads_the_smaller_value_and_learns() {
    let off = SvgConfig {
        hidden: vec![8],
        gamma: 0.9,
        learning_starts: 0,
        ..SvgConfig::default()
    };
    let on = SvgConfig {
        twin_value: true,
        ..off.clone()
    };
    let (mut svg, mut rng) = fresh(3, &on);
    // The step's objective at zero noise is the lookahead at horizon 1,
    // which reads the smaller value; it is below the first network's.
    let (batch, policy, mu, zero) = at_the_mean(&mut svg, &mut rng);
    let (obj, _) = svg.policy_objective(&batch, &zero, &ReachReward).unwrap();
    let scores = svg
        .lookahead_scores(&policy, batch.states.view(), mu.view(), None, 1)
        .unwrap();
    let rewards: Vec<f64> = (0..16)
        .map(|i| reach_reward(&batch.states.row(i).to_vec(), &mu.row(i).to_vec()))
        .collect();
    let mean = scores.iter().zip(&rewards).map(|(v, r)| v + r).sum::<f64>() / 16.0;
    assert!((mean - obj).abs() < 1e-5, "{mean} against {obj}");
    // The same learner without its second network reads a larger value
    // on some rows and never a smaller one.
    let json = serde_json::to_value(&svg).unwrap();
    assert_eq!(json["config"]["twin_value"], serde_json::json!(true));
    let mut single = json.clone();
    single.as_object_mut().unwrap().remove("twin");
    single["config"]
        .as_object_mut()
        .unwrap()
        .remove("twin_value");
    let single: Svg1 = serde_json::from_value(single).unwrap();
    let first = single
        .lookahead_scores(&policy, batch.states.view(), mu.view(), None, 1)
        .unwrap();
    assert!(first.iter().zip(&scores).all(|(a, b)| a >= b));
    assert!(first.iter().zip(&scores).any(|(a, b)| a > b));
    // The gradient against finite differences, at the replayed noise.
    let inputs = svg.policy_inputs(&batch).unwrap();
    let analytic = check_policy_gradient(&svg, &batch, &inputs, &mut rng);
    assert!(analytic.abs() > 1e-4, "analytic {analytic}");
    // Off: neither the setting nor a second network is written.
    let (plain, _) = fresh(3, &off);
    let json = serde_json::to_string(&plain).unwrap();
    assert!(!json.contains("twin"), "{}", &json[..200]);
    // It learns to reach, and a saved learner goes on identically.
    let reach = SvgConfig {
        twin_value: true,
        ..reach_config()
    };
    let (learned, _) = run_with(&reach, 5, 8_000);
    let after = eval_distance(learned.policy(), 10);
    assert!(after < 0.2, "final distance {after}");
    let (mut a, mut rng_a) = fresh(
        2,
        &SvgConfig {
            twin_value: true,
            ..small_config()
        },
    );
    train_plain(&mut a, 200, &mut rng_a);
    let saved = serde_json::to_string(&(&a, &rng_a)).unwrap();
    let (mut b, mut rng_b): (Svg1, ChaCha8Rng) = serde_json::from_str(&saved).unwrap();
    train_plain(&mut a, 200, &mut rng_a);
    train_plain(&mut b, 200, &mut rng_b);
    assert_eq!(a.policy(), b.policy());
}
