//! `red-cli mujoco table`: the grid of paper Table 1 (tasks x methods x
//! seeds), run in parallel, then a markdown and CSV table with both
//! protocols (final policy; best checkpoint by training true return) and a
//! learning-curve PNG per task (paper Fig. 4).
//!
//! Each cell is a run folder `<out-dir>/<name>/runs/<task>-<method>-s<seed>/`
//! of `red-cli mujoco train`; a finished run is reused, an interrupted one
//! resumed, so the command can be rerun until the grid is complete. The
//! table is built from whatever runs have finished and says which cells are
//! missing.

use std::collections::{BTreeMap, VecDeque};
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use anyhow::Context;
use clap::Args;
use indicatif::{MultiProgress, ProgressBar};
use red_mujoco::EnvId;

use crate::interrupt;
use crate::mujoco::{default_demo, expert_dir, short_name};
use crate::mujoco_run::{self, EvalFile, Method, Outcome, RunConfig, RunOptions};
use red_experiments::plot::{Panel, Series, draw_panels, mean_std};

/// Arguments of `red-cli mujoco table`.
#[derive(Debug, Args)]
pub struct TableArgs {
    /// Tasks, comma-separated (default: all five).
    #[arg(long, value_delimiter = ',')]
    envs: Vec<String>,
    /// Methods, comma-separated (default: red, ae, gail, gmmil, bc).
    #[arg(long, value_delimiter = ',', value_enum)]
    methods: Vec<Method>,
    /// Seeds, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0")]
    seeds: Vec<u64>,
    /// Environment steps of each TRPO run (the release's README example:
    /// 2,000,000; the paper: 5,000,000).
    #[arg(long, default_value_t = 2_000_000)]
    steps: u64,
    /// Name of the grid: outputs go to `<out-dir>/<name>/`.
    #[arg(long, default_value = "mujoco-table")]
    name: String,
    /// Folder of the runs.
    #[arg(long, default_value = "runs")]
    out_dir: PathBuf,
    /// Folder holding `expert-<task>/` (demos and expert evaluation)
    /// (default: `--out-dir`).
    #[arg(long)]
    experts_dir: Option<PathBuf>,
    /// Runs at once (default: the number of cores).
    #[arg(long)]
    jobs: Option<usize>,
    /// Evaluation episodes per run and protocol.
    #[arg(long, default_value_t = 50)]
    eval_episodes: usize,
    /// TRPO iterations between checkpoints.
    #[arg(long, default_value_t = 50)]
    checkpoint_every: u64,
    /// Only build the table and plots from the runs already finished.
    #[arg(long)]
    report_only: bool,
}

struct Job {
    env: EnvId,
    method: Method,
    seed: u64,
    dir: PathBuf,
}

/// Runs `red-cli mujoco table`.
pub fn run(args: TableArgs) -> anyhow::Result<()> {
    let envs: Vec<EnvId> = if args.envs.is_empty() {
        EnvId::ALL.to_vec()
    } else {
        args.envs
            .iter()
            .map(|s| s.parse::<EnvId>())
            .collect::<Result<_, _>>()?
    };
    let methods: Vec<Method> = if args.methods.is_empty() {
        vec![
            Method::Red,
            Method::Ae,
            Method::Gail,
            Method::Gmmil,
            Method::Bc,
        ]
    } else {
        args.methods.clone()
    };
    anyhow::ensure!(
        !methods.contains(&Method::Expert),
        "the experts' row comes from `red-cli mujoco expert` runs; leave `expert` out of --methods"
    );
    anyhow::ensure!(!args.seeds.is_empty(), "--seeds needs at least one seed");
    let experts_dir = args.experts_dir.clone().unwrap_or(args.out_dir.clone());
    let root = args.out_dir.join(&args.name);
    std::fs::create_dir_all(root.join("runs"))
        .with_context(|| format!("creating {}", root.display()))?;

    let mut jobs = VecDeque::new();
    for &env in &envs {
        let demo = default_demo(&experts_dir, env);
        if !demo.is_file() {
            eprintln!(
                "{}: no demonstrations at {} (run `red-cli mujoco expert --env {}` first); skipped",
                env,
                demo.display(),
                short_name(env)
            );
            continue;
        }
        for &method in &methods {
            for &seed in &args.seeds {
                let dir = root.join("runs").join(format!(
                    "{}-{}-s{seed}",
                    short_name(env),
                    method.name()
                ));
                jobs.push_back(Job {
                    env,
                    method,
                    seed,
                    dir,
                });
            }
        }
    }

    let started = std::time::Instant::now();
    if !args.report_only {
        interrupt::install();
        let jobs_n = args
            .jobs
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
            .max(1);
        let total = jobs.len();
        let queue = Mutex::new(jobs);
        let failures = Mutex::new(Vec::<String>::new());
        let multi = MultiProgress::new();
        eprintln!("{total} runs, {jobs_n} at a time, into {}", root.display());
        std::thread::scope(|scope| {
            for _ in 0..jobs_n {
                scope.spawn(|| {
                    loop {
                        if interrupt::requested() {
                            break;
                        }
                        let job = match queue.lock() {
                            Ok(mut q) => q.pop_front(),
                            Err(_) => None,
                        };
                        let Some(job) = job else { break };
                        if let Err(e) = run_job(&job, &args, &experts_dir, &multi) {
                            let msg = format!("{}: {e:#}", job.dir.display());
                            say(&multi, format!("run failed: {msg}"));
                            if let Ok(mut f) = failures.lock() {
                                f.push(msg);
                            }
                        }
                    }
                });
            }
        });
        let failures = failures.into_inner().unwrap_or_default();
        for f in &failures {
            eprintln!("failed: {f}");
        }
        if interrupt::requested() {
            eprintln!(
                "interrupted: the runs saved checkpoints; rerun the same command to continue"
            );
        }
    }
    let (md, csv) = report(&root, &envs, &methods, &args.seeds, &experts_dir, &args)?;
    red_core::checkpoint::write_atomic(&root.join("table.md"), md.as_bytes())?;
    red_core::checkpoint::write_atomic(&root.join("table.csv"), csv.as_bytes())?;
    println!("{md}");
    println!(
        "({:.0} s; table, CSV and curves in {})",
        started.elapsed().as_secs_f64(),
        root.display()
    );
    Ok(())
}

/// A line above the bars, or on stderr when they are hidden (logs).
fn say(multi: &MultiProgress, line: String) {
    if multi.is_hidden() {
        eprintln!("{line}");
    } else {
        let _ = multi.println(line);
    }
}

fn run_job(
    job: &Job,
    args: &TableArgs,
    experts_dir: &Path,
    multi: &MultiProgress,
) -> anyhow::Result<()> {
    if let Some(e) = mujoco_run::read_eval(&job.dir) {
        let cfg = mujoco_run::read_config(&job.dir)?;
        if cfg.method == Method::Bc || cfg.steps >= args.steps {
            say(
                multi,
                format!(
                    "{}: finished earlier (final {:.1})",
                    job.dir.display(),
                    e.final_policy.mean
                ),
            );
            return Ok(());
        }
    }
    let label = format!(
        "{} {} s{}",
        short_name(job.env),
        job.method.name(),
        job.seed
    );
    let bar = multi.add(ProgressBar::new(args.steps));
    bar.set_style(mujoco_run::bar_style());
    bar.set_prefix(label.clone());
    let opts = RunOptions {
        bar: bar.clone(),
        log_prefix: Some(label),
        stop_after_iterations: None,
    };
    let resume = job.dir.join("config.json").is_file();
    let cfg = if resume {
        let mut c = mujoco_run::read_config(&job.dir)?;
        c.steps = c.steps.max(args.steps);
        c
    } else {
        let mut c = RunConfig::for_task(job.env, job.method);
        c.seed = job.seed;
        c.steps = args.steps;
        c.eval_episodes = args.eval_episodes;
        c.checkpoint_every = args.checkpoint_every;
        c.demo = Some(default_demo(experts_dir, job.env));
        c
    };
    let outcome = mujoco_run::run(&job.dir, Some(cfg), resume, &opts);
    bar.finish_and_clear();
    multi.remove(&bar);
    match outcome? {
        Outcome::Finished => {
            if let Some(e) = mujoco_run::read_eval(&job.dir) {
                say(
                    multi,
                    format!(
                        "{}: final {:.1} +- {:.1}{} ({:.0} s)",
                        job.dir.display(),
                        e.final_policy.mean,
                        e.final_policy.std,
                        e.best_checkpoint
                            .as_ref()
                            .map_or(String::new(), |b| format!(
                                ", best checkpoint {:.1} +- {:.1}",
                                b.mean, b.std
                            )),
                        e.wall_s
                    ),
                );
            }
        }
        Outcome::Interrupted => {}
    }
    Ok(())
}

/// Pooled mean and std over every evaluation episode of the seeds.
struct Cell {
    mean: f64,
    std: f64,
    seeds: usize,
    episodes: usize,
    per_seed: Vec<f64>,
    steps: u64,
}

fn cell(evals: &[&EvalFile], best: bool) -> Option<Cell> {
    let parts: Vec<_> = evals
        .iter()
        .filter_map(|e| {
            if best {
                e.best_checkpoint.as_ref()
            } else {
                Some(&e.final_policy)
            }
        })
        .collect();
    if parts.is_empty() {
        return None;
    }
    let pooled: Vec<f64> = parts
        .iter()
        .flat_map(|p| p.returns.iter().copied())
        .collect();
    let (mean, std) = mean_std(&pooled);
    Some(Cell {
        mean,
        std,
        seeds: parts.len(),
        episodes: pooled.len(),
        per_seed: parts.iter().map(|p| p.mean).collect(),
        steps: parts.iter().map(|p| p.env_steps).max().unwrap_or(0),
    })
}

fn fmt_cell(c: &Option<Cell>, missing: usize) -> String {
    match c {
        None => "not run".into(),
        Some(c) => {
            let mut s = format!("{:.2} ± {:.2}", c.mean, c.std);
            if c.seeds > 1 {
                s.push_str(&format!(" ({} seeds)", c.seeds));
            }
            if missing > 0 {
                s.push_str(&format!(" [partial: {missing} seed(s) missing]"));
            }
            s
        }
    }
}

/// Reads `(env_steps, true_return_window)` of a run's metrics.
fn read_curve(dir: &Path) -> Vec<(u64, f64)> {
    let Ok(f) = std::fs::File::open(dir.join("metrics.csv")) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for line in std::io::BufReader::new(f)
        .lines()
        .skip(1)
        .map_while(Result::ok)
    {
        let cols: Vec<&str> = line.split(',').collect();
        if cols.len() > 4
            && let (Ok(s), Ok(w)) = (cols[1].parse::<u64>(), cols[4].parse::<f64>())
        {
            out.push((s, w));
        }
    }
    out
}

fn report(
    root: &Path,
    envs: &[EnvId],
    methods: &[Method],
    seeds: &[u64],
    experts_dir: &Path,
    args: &TableArgs,
) -> anyhow::Result<(String, String)> {
    let mut evals: BTreeMap<(usize, usize), Vec<EvalFile>> = BTreeMap::new();
    for (ei, &env) in envs.iter().enumerate() {
        for (mi, &m) in methods.iter().enumerate() {
            for &seed in seeds {
                let dir =
                    root.join("runs")
                        .join(format!("{}-{}-s{seed}", short_name(env), m.name()));
                if let Some(e) = mujoco_run::read_eval(&dir) {
                    evals.entry((ei, mi)).or_default().push(e);
                }
            }
        }
    }
    let experts: Vec<Option<(EvalFile, f64, f64)>> = envs
        .iter()
        .map(|&env| {
            let e = mujoco_run::read_eval(&expert_dir(experts_dir, env))?;
            let chosen = match e.expert_choice.as_deref() {
                Some("best checkpoint") => e.best_checkpoint.clone()?,
                _ => e.final_policy.clone(),
            };
            Some((e, chosen.mean, chosen.std))
        })
        .collect();

    let mut md = String::new();
    md.push_str(&format!(
        "Grid `{}`: TRPO budget {} env steps per run; seeds {:?}; each cell is the mean ± std of the true return over every evaluation episode of its seeds ({} per seed, deterministic actions).\n\n",
        args.name, args.steps, seeds, args.eval_episodes
    ));
    let header = |md: &mut String| {
        md.push_str("| method |");
        for env in envs {
            md.push_str(&format!(" {env} |"));
        }
        md.push_str("\n|---|");
        for _ in envs {
            md.push_str("---|");
        }
        md.push('\n');
    };
    let mut csv =
        String::from("env,method,protocol,seeds,episodes,mean,std,per_seed_means,env_steps\n");
    for (best, title) in [
        (false, "Final policy"),
        (
            true,
            "Best checkpoint by mean true return of the last 40 training episodes (the paper's protocol: selected with the true reward)",
        ),
    ] {
        md.push_str(&format!("### {title}\n\n"));
        header(&mut md);
        md.push_str("| Expert (its policy; mean of its 4 demos) |");
        for ex in &experts {
            match ex {
                Some((e, m, sd)) => md.push_str(&format!(
                    " {m:.2} ± {sd:.2} ({:.2}) |",
                    e.demo_returns.as_ref().map_or(f64::NAN, |r| mean_std(r).0)
                )),
                None => md.push_str(" no expert run |"),
            }
        }
        md.push('\n');
        for (mi, &m) in methods.iter().enumerate() {
            if best && m == Method::Bc {
                continue;
            }
            md.push_str(&format!("| {} |", m.label()));
            for (ei, &env) in envs.iter().enumerate() {
                let list: Vec<&EvalFile> = evals
                    .get(&(ei, mi))
                    .map(|v| v.iter().collect())
                    .unwrap_or_default();
                let c = cell(&list, best);
                let missing = seeds.len() - list.len();
                let started = seeds.iter().any(|s| {
                    root.join("runs")
                        .join(format!("{}-{}-s{s}", short_name(env), m.name()))
                        .join("config.json")
                        .is_file()
                });
                let text = match (&c, started) {
                    (None, true) => "unfinished".to_string(),
                    _ => fmt_cell(&c, if c.is_some() { missing } else { 0 }),
                };
                md.push_str(&format!(" {text} |"));
                if let Some(c) = &c {
                    csv.push_str(&format!(
                        "{},{},{},{},{},{},{},{},{}\n",
                        env.name(),
                        m.name(),
                        if best { "best_checkpoint" } else { "final" },
                        c.seeds,
                        c.episodes,
                        c.mean,
                        c.std,
                        c.per_seed
                            .iter()
                            .map(|x| format!("{x:.3}"))
                            .collect::<Vec<_>>()
                            .join(";"),
                        c.steps
                    ));
                }
            }
            md.push('\n');
        }
        md.push('\n');
    }

    // Learning curves per task.
    for (ei, &env) in envs.iter().enumerate() {
        let mut series = Vec::new();
        let mut x_end: f64 = 0.0;
        for (mi, &m) in methods.iter().enumerate() {
            if m == Method::Bc {
                continue;
            }
            let curves: Vec<Vec<(u64, f64)>> = seeds
                .iter()
                .map(|&s| {
                    read_curve(&root.join("runs").join(format!(
                        "{}-{}-s{s}",
                        short_name(env),
                        m.name()
                    )))
                })
                .filter(|c| !c.is_empty())
                .collect();
            if curves.is_empty() {
                continue;
            }
            let n = curves.iter().map(Vec::len).min().unwrap_or(0);
            let mut points = Vec::new();
            let mut band = Vec::new();
            for i in 0..n {
                let x = curves[0][i].0 as f64;
                let ys: Vec<f64> = curves.iter().map(|c| c[i].1).collect();
                let (mu, sd) = mean_std(&ys);
                points.push((x, mu));
                if curves.len() > 1 {
                    band.push((x, mu - sd, mu + sd));
                }
            }
            x_end = x_end.max(points.last().map_or(0.0, |p| p.0));
            let _ = mi;
            series.push(Series {
                label: format!("{} ({} seed(s))", m.label(), curves.len()),
                points,
                band,
            });
        }
        if series.is_empty() {
            continue;
        }
        if let Some(bi) = methods.iter().position(|&m| m == Method::Bc)
            && let Some(list) = evals.get(&(ei, bi))
        {
            let refs: Vec<&EvalFile> = list.iter().collect();
            if let Some(c) = cell(&refs, false) {
                series.push(Series {
                    label: "BC (evaluation)".into(),
                    points: vec![(0.0, c.mean), (x_end, c.mean)],
                    band: Vec::new(),
                });
            }
        }
        if let Some((_, m, _)) = &experts[ei] {
            series.push(Series {
                label: "expert (evaluation)".into(),
                points: vec![(0.0, *m), (x_end, *m)],
                band: Vec::new(),
            });
        }
        let png = root.join(format!("curve-{}.png", short_name(env)));
        draw_panels(
            &png,
            &[Panel {
                title: format!("{env}: true return of the last 40 training episodes"),
                x_label: "environment steps".into(),
                y_label: "true return".into(),
                series,
                y_range: None,
            }],
            1,
            (900, 550),
        )?;
        md.push_str(&format!("Learning curve: `{}`\n", png.display()));
    }
    Ok((md, csv))
}
