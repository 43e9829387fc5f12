//! `red-cli drive --demo FILE`: imitation on the driving scenario (paper
//! Sec. 5.3). RED fits an RND support estimator on the demonstration, sets
//! `σ1` from held-out expert scores (5 folds), warm-starts a Gaussian policy
//! by behaviour cloning and improves it with SVG(1)-ER on RED's reward plus
//! the terminal heuristic. `bc` is the warm-started policy alone. Each method
//! is evaluated with deterministic actions on the demonstration's road.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use red_core::{Demos, Env, EpisodeEnd, Trajectory};
use red_drive::render::demo_path;
use red_drive::{ACT_DIM, DriveConfig, ENV_ID, OBS_DIM, RenderOptions, make_env, render_png};
use red_rl::bc::{BcConfig, behavior_clone};
use red_rl::normalize::ObsNormalizer;
use red_rl::policy::{GaussianPolicy, GaussianPolicyConfig};
use red_rl::svg::{Svg1, SvgConfig};
use red_support::{
    RedReward, RedRewardConfig, RndConfig, Sigma1, SupportEstimatorConfig, TerminalHeuristic,
    TerminalHeuristicConfig, calibrate_sigma1, held_out_scores, no_progress,
};
use serde::Serialize;

use crate::drive::{TrackArgs, load_config};
use crate::plot::{Panel, Series, draw_panels, mean_std, palette};

/// Arguments of `red-cli drive --demo FILE` (training and evaluation).
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// Demonstration file (`drive` scenario) to imitate.
    #[arg(long)]
    pub demo: Option<PathBuf>,
    /// Methods, comma-separated: `red` (RED reward + SVG(1)-ER, warm-started
    /// by BC) and `bc` (behaviour cloning alone).
    #[arg(long, default_value = "red,bc", value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Seed of everything random (fits, exploration, start noise).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Environment steps of SVG(1)-ER for `red`.
    #[arg(long, default_value_t = 20_000)]
    pub steps: u64,
    /// Run name: outputs go to `<out-dir>/<name>/`.
    #[arg(long, default_value = "drive")]
    pub name: String,
    /// Folder of the runs.
    #[arg(long, default_value = "runs")]
    pub out_dir: PathBuf,
    /// Training epochs of the RND predictor (the release's 200).
    #[arg(long, default_value_t = 200)]
    pub rnd_epochs: usize,
    /// Behaviour-cloning epochs of the warm start.
    #[arg(long, default_value_t = 200)]
    pub bc_epochs: usize,
    /// Evaluation episodes per method.
    #[arg(long, default_value_t = 5)]
    pub eval_runs: usize,
    /// The road (default: the default road, the shipped demo's).
    #[command(flatten)]
    pub track: TrackArgs,
}

/// Everything that decides a run, written to `config.json`.
#[derive(Debug, Serialize)]
struct RunConfig {
    demo: String,
    methods: Vec<String>,
    seed: u64,
    steps: u64,
    eval_runs: usize,
    drive: DriveConfig,
    rnd: RndConfig,
    sigma1_rule: &'static str,
    terminal: TerminalHeuristicConfig,
    policy: GaussianPolicyConfig,
    bc: BcConfig,
    svg: SvgConfig,
}

/// One method's evaluation.
#[derive(Debug, Serialize)]
struct MethodEval {
    method: String,
    distances: Vec<f64>,
    mean: f64,
    std: f64,
    best: f64,
    percent_of_road: f64,
}

/// The policy's settings: the release's network, an initial standard
/// deviation of e^-1 ~ 0.37 (our choice: exploration of a third of the
/// action range; BC trains only the mean).
fn policy_config() -> GaussianPolicyConfig {
    GaussianPolicyConfig {
        init_log_std: -1.0,
        ..GaussianPolicyConfig::default()
    }
}

/// Rolls out `policy` deterministically for `runs` episodes (reset seeds
/// `1000 + i`); returns the distances and the trajectories.
fn evaluate(
    config: &DriveConfig,
    policy: &GaussianPolicy,
    runs: usize,
) -> anyhow::Result<(Vec<f64>, Vec<Trajectory>)> {
    let mut env = make_env(config)?;
    let mut distances = Vec::new();
    let mut trajs = Vec::new();
    for i in 0..runs {
        let (mut obs, _) = env.reset(Some(1_000 + i as u64))?;
        let (mut observations, mut actions, mut rewards) = (Vec::new(), Vec::new(), Vec::new());
        let end = loop {
            let a = policy.act_deterministic(&obs)?;
            let step = env.step(&a)?;
            observations.push(obs);
            actions.push(a);
            rewards.push(step.reward);
            obs = step.observation;
            if step.terminated {
                break EpisodeEnd::Terminated;
            }
            if step.truncated {
                break EpisodeEnd::Truncated;
            }
        };
        distances.push(rewards.iter().sum());
        trajs.push(Trajectory {
            observations,
            actions,
            rewards: Some(rewards),
            end,
        });
    }
    Ok((distances, trajs))
}

fn load_demo(path: &Path) -> anyhow::Result<Demos> {
    let demos = Demos::read(path).with_context(|| format!("reading {}", path.display()))?;
    if demos.env_id != ENV_ID {
        bail!(
            "{} holds demonstrations of `{}`; `drive --demo` needs `{ENV_ID}` ones",
            path.display(),
            demos.env_id
        );
    }
    if demos.obs_dim != OBS_DIM || demos.act_dim != ACT_DIM {
        bail!(
            "{} has observations of {} and actions of {} numbers; the drive scenario has {OBS_DIM} and {ACT_DIM}",
            path.display(),
            demos.obs_dim,
            demos.act_dim
        );
    }
    if demos.num_pairs() < 10 {
        bail!(
            "{} has only {} state-action pairs; need at least 10",
            path.display(),
            demos.num_pairs()
        );
    }
    Ok(demos)
}

/// Runs `red-cli drive --demo FILE`.
pub fn run(args: TrainArgs) -> anyhow::Result<()> {
    let demo_path_arg = args.demo.clone().context("--demo is required")?;
    for m in &args.methods {
        if m != "red" && m != "bc" {
            bail!("unknown method `{m}` (drive supports red and bc)");
        }
    }
    if args.eval_runs == 0 {
        bail!("--eval-runs must be at least 1");
    }
    let started = std::time::Instant::now();
    let demos = load_demo(&demo_path_arg)?;
    let config = load_config(&args.track)?;
    let (es, ea) = demos.pairs();
    let out = args.out_dir.join(&args.name);
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;

    let rnd = RndConfig {
        epochs: args.rnd_epochs,
        ..RndConfig::default()
    };
    let terminal_cfg = TerminalHeuristicConfig::default();
    let bc_cfg = BcConfig {
        epochs: args.bc_epochs,
        ..BcConfig::default()
    };
    let svg_cfg = SvgConfig::default();
    let run_config = RunConfig {
        demo: demo_path_arg.display().to_string(),
        methods: args.methods.clone(),
        seed: args.seed,
        steps: args.steps,
        eval_runs: args.eval_runs,
        drive: config.clone(),
        rnd: rnd.clone(),
        sigma1_rule: "0.9 quantile of 5-fold held-out expert scores gets reward 0.9",
        terminal: terminal_cfg.clone(),
        policy: policy_config(),
        bc: bc_cfg.clone(),
        svg: svg_cfg.clone(),
    };
    std::fs::write(
        out.join("config.json"),
        serde_json::to_string_pretty(&run_config)?,
    )?;

    // Warm start shared by both methods.
    let mut rng = ChaCha8Rng::seed_from_u64(args.seed);
    let mut norm = ObsNormalizer::from_data(es.view(), 5.0, 1e-2)?;
    norm.freeze();
    let mut policy = GaussianPolicy::new(&policy_config(), OBS_DIM, ACT_DIM, Some(norm), &mut rng)?;
    behavior_clone(&mut policy, es.view(), ea.view(), &bc_cfg, &mut rng)?;

    let expert_distance: f64 = demos
        .trajectories
        .iter()
        .map(|t| t.true_return().unwrap_or(f64::NAN))
        .sum::<f64>()
        / demos.trajectories.len() as f64;
    let mut evals = Vec::new();
    let mut eval_trajs: Vec<(String, Vec<Trajectory>)> = Vec::new();
    let mut metrics = String::from("method,env_steps,distance,imitation_return,length\n");
    let mut curve: Vec<(f64, f64)> = Vec::new();

    for method in &args.methods {
        let trained = match method.as_str() {
            "bc" => policy.clone(),
            _ => {
                let mut rrng = ChaCha8Rng::seed_from_u64(args.seed.wrapping_add(1));
                eprintln!("fitting RND on {} expert pairs ...", es.nrows());
                let model = rnd.fit(es.view(), ea.view(), &mut rrng, &mut no_progress)?;
                let scores = held_out_scores(&rnd, es.view(), ea.view(), 5, &mut rrng)?;
                let (q, r) = match RedRewardConfig::default().sigma1 {
                    Sigma1::Calibrated { quantile, reward } => (quantile, reward),
                    Sigma1::Fixed(_) => (0.9, 0.9),
                };
                let sigma1 = calibrate_sigma1(&scores.to_vec(), q, r)?;
                let reward = RedReward::with_sigma1(model, sigma1)?;
                let heuristic =
                    TerminalHeuristic::new(&terminal_cfg, &reward, es.view(), ea.view())?;
                eprintln!(
                    "sigma1 = {sigma1:.4}, mean expert reward {:.3}",
                    heuristic.expert_mean_reward()
                );
                let mut srng = ChaCha8Rng::seed_from_u64(args.seed.wrapping_add(2));
                let mut svg = Svg1::new(&svg_cfg, policy.clone(), &mut srng)?;
                let mut env = make_env(&config)?;
                let bar = ProgressBar::new(args.steps);
                bar.set_style(
                    ProgressStyle::with_template(
                        "red/SVG {bar:30} {pos}/{len} steps, {elapsed} ({eta} left) {msg}",
                    )
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
                );
                let mut recent: Vec<f64> = Vec::new();
                svg.train(
                    &mut env,
                    &reward,
                    args.steps,
                    None,
                    &|r| heuristic.penalty(r),
                    &mut srng,
                    &mut |e| {
                        metrics.push_str(&format!(
                            "{method},{},{},{},{}\n",
                            e.env_steps, e.true_return, e.imitation_return, e.length
                        ));
                        recent.push(e.true_return);
                        let k = recent.len().saturating_sub(10);
                        let avg = recent[k..].iter().sum::<f64>() / (recent.len() - k) as f64;
                        curve.push((e.env_steps as f64, avg));
                        bar.set_position(e.env_steps);
                        bar.set_message(format!("distance (last 10) {avg:.0} m"));
                    },
                )?;
                bar.finish_and_clear();
                svg.into_policy()
            }
        };
        let (distances, trajs) = evaluate(&config, &trained, args.eval_runs)?;
        let (mean, std) = mean_std(&distances);
        let best = distances.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        evals.push(MethodEval {
            method: method.clone(),
            mean,
            std,
            best,
            percent_of_road: 100.0 * mean / config.road_length,
            distances,
        });
        eval_trajs.push((method.clone(), trajs));
    }

    std::fs::write(out.join("metrics.csv"), &metrics)?;
    #[derive(Serialize)]
    struct EvalFile<'a> {
        expert_distance: f64,
        road_length: f64,
        methods: &'a [MethodEval],
    }
    std::fs::write(
        out.join("eval.json"),
        serde_json::to_string_pretty(&EvalFile {
            expert_distance,
            road_length: config.road_length,
            methods: &evals,
        })?,
    )?;

    // Learning curve of RED (BC's evaluation as a flat reference).
    if !curve.is_empty() {
        let mut series = vec![Series {
            label: "RED + SVG(1)-ER (last 10 episodes)".into(),
            points: curve.clone(),
            band: Vec::new(),
        }];
        let x_end = curve.last().map_or(1.0, |p| p.0);
        if let Some(bc) = evals.iter().find(|e| e.method == "bc") {
            series.push(Series {
                label: "BC (evaluation)".into(),
                points: vec![(0.0, bc.mean), (x_end, bc.mean)],
                band: Vec::new(),
            });
        }
        series.push(Series {
            label: "expert demo".into(),
            points: vec![(0.0, expert_distance), (x_end, expert_distance)],
            band: Vec::new(),
        });
        draw_panels(
            &out.join("learning_curve.png"),
            &[Panel {
                title: "drive: distance per training episode".into(),
                x_label: "environment steps".into(),
                y_label: "distance (m)".into(),
                series,
                y_range: Some((0.0, config.road_length * 1.05)),
            }],
            1,
            (900, 500),
        )?;
    }

    // Evaluation paths on the road, with the demonstration.
    let mut paths = Vec::new();
    for (i, t) in demos.trajectories.iter().enumerate() {
        paths.push(demo_path(&config, t, format!("expert {i}"), [0, 0, 0], 0)?);
    }
    for (mi, (m, trajs)) in eval_trajs.iter().enumerate() {
        let c = palette(mi);
        for (i, t) in trajs.iter().enumerate() {
            paths.push(demo_path(
                &config,
                t,
                format!("{m} {i}"),
                [c.0, c.1, c.2],
                0,
            )?);
        }
    }
    render_png(
        &out.join("eval_paths.png"),
        &config,
        &paths,
        &RenderOptions::default(),
    )?;

    let mut so = std::io::stdout().lock();
    writeln!(
        so,
        "{:<8} {:>10} {:>8} {:>8} {:>8}",
        "method", "distance", "std", "best", "% road"
    )?;
    writeln!(
        so,
        "{:<8} {:>10.1} {:>8} {:>8.1} {:>8.1}",
        "expert",
        expert_distance,
        "-",
        expert_distance,
        100.0 * expert_distance / config.road_length
    )?;
    for e in &evals {
        writeln!(
            so,
            "{:<8} {:>10.1} {:>8.1} {:>8.1} {:>8.1}",
            e.method, e.mean, e.std, e.best, e.percent_of_road
        )?;
    }
    writeln!(
        so,
        "({} evaluation runs per method, deterministic actions; {:.0} s; outputs in {})",
        args.eval_runs,
        started.elapsed().as_secs_f64(),
        out.display()
    )?;
    Ok(())
}
