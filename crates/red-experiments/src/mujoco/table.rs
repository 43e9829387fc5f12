//! The grid of paper Table 1 (tasks x methods x seeds), run in parallel,
//! then a markdown and CSV table with both protocols (final policy; best
//! checkpoint by training true return) and a learning-curve PNG per task
//! (paper Fig. 4).
//!
//! Each cell is a run folder `<out_dir>/<name>/runs/<task>-<method>-s<seed>/`
//! of [`super::launch::run`]; a finished run is reused, an interrupted one resumed, so
//! the grid can be rerun until it is complete. The table is built from
//! whatever runs have finished and says which cells are missing.

use std::collections::BTreeMap;
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use red_mujoco::EnvId;
use serde::{Deserialize, Serialize};

use super::run::{self, EvalFile, EvalSummary, Outcome, RunConfig};
use super::{Method, default_demo, expert_dir, short_name};
use crate::grid::OnFailure;
use crate::plot::{Panel, Series, draw_panels, mean_std};
use crate::{Error, Progress, Result};

/// The grid: which runs, their budget, and where they go.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TableConfig {
    /// Tasks. Default: all five ([`EnvId::ALL`]).
    pub envs: Vec<EnvId>,
    /// Methods. Default: red, ae, gail, gmmil, bc ([`Method::TABLE`]); the
    /// experts' row comes from expert runs, so `expert` is refused.
    pub methods: Vec<Method>,
    /// Seeds. Default: `[0]`.
    pub seeds: Vec<u64>,
    /// Environment steps of each TRPO run. Default 2,000,000 (the
    /// release's README example; the paper: 5,000,000).
    pub steps: u64,
    /// Name of the grid: outputs go to `<out_dir>/<name>/`. Default
    /// `mujoco-table`.
    pub name: String,
    /// Folder of the runs. Default `runs`.
    pub out_dir: PathBuf,
    /// Folder holding `expert-<task>/` (demos and expert evaluation).
    /// Default: `out_dir`.
    pub experts_dir: Option<PathBuf>,
    /// Runs at once. Default: the number of cores.
    pub jobs: Option<usize>,
    /// Evaluation episodes per run and protocol. Default 50 (the paper).
    pub eval_episodes: usize,
    /// TRPO iterations between checkpoints. Default 50.
    pub checkpoint_every: u64,
}

impl Default for TableConfig {
    fn default() -> Self {
        Self {
            envs: EnvId::ALL.to_vec(),
            methods: Method::TABLE.to_vec(),
            seeds: vec![0],
            steps: 2_000_000,
            name: "mujoco-table".into(),
            out_dir: PathBuf::from("runs"),
            experts_dir: None,
            jobs: None,
            eval_episodes: 50,
            checkpoint_every: 50,
        }
    }
}

impl TableConfig {
    /// This grid with its tasks and methods replaced by `envs` and
    /// `methods` where they are not empty (the command line's "default:
    /// all"), then checked.
    ///
    /// # Errors
    /// As [`TableConfig::validate`].
    pub fn with_grid(mut self, envs: Vec<EnvId>, methods: Vec<Method>) -> Result<Self> {
        if !envs.is_empty() {
            self.envs = envs;
        }
        if !methods.is_empty() {
            self.methods = methods;
        }
        self.validate()?;
        Ok(self)
    }

    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        let bad = |field: &str, reason: &str| {
            Err(Error::InvalidConfig {
                field: field.into(),
                reason: reason.into(),
            })
        };
        if self.methods.contains(&Method::Expert) {
            return bad(
                "methods",
                "the experts' row comes from `red-cli mujoco expert` runs; leave `expert` out of --methods",
            );
        }
        if self.seeds.is_empty() {
            return bad("seeds", "needs at least one seed");
        }
        if self.envs.is_empty() || self.methods.is_empty() {
            return bad("envs", "needs at least one task and one method");
        }
        if self.steps == 0 {
            return bad("steps", "must be at least 1");
        }
        if self.checkpoint_every == 0 {
            return bad("checkpoint_every", "must be at least 1");
        }
        if self.eval_episodes == 0 {
            return bad("eval_episodes", "must be at least 1");
        }
        if self.jobs == Some(0) {
            return bad(
                "jobs",
                "must be at least 1 (leave it out to use every core)",
            );
        }
        crate::run_dir::check_name(&self.name)?;
        Ok(())
    }

    /// The grid's folder: `<out_dir>/<name>`.
    pub fn root(&self) -> PathBuf {
        self.out_dir.join(&self.name)
    }

    /// Where the experts are.
    pub fn experts_dir(&self) -> &Path {
        self.experts_dir.as_deref().unwrap_or(&self.out_dir)
    }

    /// The run folder of one cell.
    pub fn cell_dir(&self, env: EnvId, method: Method, seed: u64) -> PathBuf {
        self.root()
            .join("runs")
            .join(format!("{}-{}-s{seed}", short_name(env), method.name()))
    }
}

/// What the grid tells its caller while its cells run in parallel.
pub trait GridProgress: Sync {
    /// A line about the grid (a cell finished, failed or skipped).
    fn note(&self, text: &str);
    /// The observer of the cell `label` (`hopper red s0`), used by the one
    /// worker thread that runs it and dropped when the cell ends.
    fn cell(&self, label: &str) -> Box<dyn Progress + '_>;
}

/// A [`GridProgress`] that ignores everything.
impl GridProgress for crate::Silent {
    fn note(&self, _text: &str) {}
    fn cell(&self, _label: &str) -> Box<dyn Progress + '_> {
        Box::new(crate::Silent)
    }
}

/// How [`run_grid`] ended.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct GridOutcome {
    /// Cells that failed: `<run folder>: <error>`.
    pub failures: Vec<String>,
    /// Whether the stop flag ended the grid early (the running cells saved
    /// checkpoints; running the grid again continues).
    pub interrupted: bool,
}

impl GridOutcome {
    /// What the user should know: one `failed: ...` line per failed cell,
    /// and how to continue an interrupted grid; each ends with a newline.
    pub fn notes(&self) -> String {
        let mut text: String = self
            .failures
            .iter()
            .map(|f| format!("failed: {f}\n"))
            .collect();
        if self.interrupted {
            text += "interrupted: the runs saved checkpoints; rerun the same command to continue\n";
        }
        text
    }
}

/// One cell of the grid: a task, a method, a seed and its run folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GridCell {
    /// The task.
    pub env: EnvId,
    /// The method.
    pub method: Method,
    /// The seed.
    pub seed: u64,
    /// Its run folder ([`TableConfig::cell_dir`]).
    pub dir: PathBuf,
}

impl TableConfig {
    /// Every cell of the grid, task by task, then method, then seed (the
    /// order of the table and of a SLURM job array).
    pub fn cells(&self) -> Vec<GridCell> {
        let mut out = Vec::new();
        for &env in &self.envs {
            for &method in &self.methods {
                for &seed in &self.seeds {
                    out.push(GridCell {
                        env,
                        method,
                        seed,
                        dir: self.cell_dir(env, method, seed),
                    });
                }
            }
        }
        out
    }
}

/// Whether the cell's run in `dir` has finished with the grid's budget (an
/// `eval.json`, and for TRPO methods a `config.json` budget of at least
/// `cfg.steps`): the grid keeps it instead of running it again.
pub fn cell_finished(cfg: &TableConfig, dir: &Path) -> bool {
    run::read_eval(dir).is_some()
        && run::read_config(dir).is_ok_and(|c| c.method == Method::Bc || c.steps >= cfg.steps)
}

/// Runs every cell of the grid whose task has demonstrations, `jobs` at a
/// time; finished cells are kept, interrupted ones resumed.
///
/// # Errors
/// A bad config or a grid folder that cannot be created; the failures of
/// single cells are in [`GridOutcome::failures`] instead.
pub fn run_grid(
    cfg: &TableConfig,
    stop: &AtomicBool,
    progress: &dyn GridProgress,
) -> Result<GridOutcome> {
    cfg.validate()?;
    let root = cfg.root();
    let runs = root.join("runs");
    std::fs::create_dir_all(&runs).map_err(|source| Error::Io { path: runs, source })?;
    let mut jobs = Vec::new();
    for &env in &cfg.envs {
        let demo = default_demo(cfg.experts_dir(), env);
        if !demo.is_file() {
            progress.note(&format!(
                "{}: no demonstrations at {} (run `red-cli mujoco expert --env {}` first); skipped",
                env,
                demo.display(),
                short_name(env)
            ));
            continue;
        }
        jobs.extend(cfg.cells().into_iter().filter(|c| c.env == env));
    }
    let jobs_n = cfg.jobs.unwrap_or_else(crate::cores).max(1);
    progress.note(&format!(
        "{} runs, {jobs_n} at a time, into {}",
        jobs.len(),
        root.display()
    ));
    let failures = crate::grid::run_pool(jobs.len(), jobs_n, stop, OnFailure::Continue, |i| {
        let job = &jobs[i];
        run_job(job, cfg, stop, progress).map_err(|e| {
            let msg = format!("{}: {e}", job.dir.display());
            progress.note(&format!("run failed: {msg}"));
            msg
        })
    });
    Ok(GridOutcome {
        failures: failures.into_iter().map(|(_, m)| m).collect(),
        interrupted: stop.load(Ordering::SeqCst),
    })
}

fn run_job(
    job: &GridCell,
    cfg: &TableConfig,
    stop: &AtomicBool,
    progress: &dyn GridProgress,
) -> Result<()> {
    if cell_finished(cfg, &job.dir)
        && let Some(e) = run::read_eval(&job.dir)
    {
        progress.note(&format!(
            "{}: finished earlier (final {:.1})",
            job.dir.display(),
            e.final_policy.mean
        ));
        return Ok(());
    }
    let label = format!(
        "{} {} s{}",
        short_name(job.env),
        job.method.name(),
        job.seed
    );
    let resume = job.dir.join("config.json").is_file();
    let run_cfg = if resume {
        let mut c = run::read_config(&job.dir)?;
        c.steps = c.steps.max(cfg.steps);
        c
    } else {
        let mut c = RunConfig::for_task(job.env, job.method);
        c.seed = job.seed;
        c.steps = cfg.steps;
        c.eval_episodes = cfg.eval_episodes;
        c.checkpoint_every = cfg.checkpoint_every;
        c.demo = Some(default_demo(cfg.experts_dir(), job.env));
        c
    };
    let outcome = {
        let mut cell = progress.cell(&label);
        super::launch::run(&job.dir, Some(run_cfg), resume, stop, &mut *cell)
    };
    if outcome? == Outcome::Finished
        && let Some(e) = run::read_eval(&job.dir)
    {
        progress.note(&format!(
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
        ));
    }
    Ok(())
}

/// The grid's table: markdown (both protocols, then the learning curves'
/// files) and CSV, as written to `table.md` and `table.csv`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TableReport {
    /// `table.md`.
    pub markdown: String,
    /// `table.csv`.
    pub csv: String,
}

impl TableReport {
    /// The table and where it was written (with the grid's `seconds`), as
    /// `red-cli mujoco table` prints it.
    pub fn summary(&self, cfg: &TableConfig, seconds: f64) -> String {
        format!(
            "{}\n({seconds:.0} s; table, CSV and curves in {})\n",
            self.markdown,
            cfg.root().display()
        )
    }
}

/// Builds the table and the learning-curve PNGs from the runs that have
/// finished, and writes `table.md`, `table.csv` and `curve-<task>.png` into
/// the grid's folder.
///
/// # Errors
/// A file that cannot be written or a picture that cannot be drawn.
pub fn write_report(cfg: &TableConfig) -> Result<TableReport> {
    let root = cfg.root();
    std::fs::create_dir_all(&root).map_err(|source| Error::Io {
        path: root.clone(),
        source,
    })?;
    let (markdown, csv) = report(&root, cfg)?;
    red_core::checkpoint::write_atomic(&root.join("table.md"), markdown.as_bytes())?;
    red_core::checkpoint::write_atomic(&root.join("table.csv"), csv.as_bytes())?;
    Ok(TableReport { markdown, csv })
}

/// One cell of the table: the runs of one (task, method) under one protocol.
struct Cell {
    /// Mean over the seeds of each seed's mean return (with equal episodes
    /// per seed, also the mean over every episode).
    mean: f64,
    /// Standard deviation (population) over every evaluation episode of the
    /// seeds, pooled.
    std: f64,
    /// Standard deviation (population) across the seeds' means: the spread
    /// the table shows when there is more than one seed.
    seed_std: f64,
    seeds: usize,
    episodes: usize,
    per_seed: Vec<f64>,
    steps: u64,
}

fn cell(evals: &[&EvalFile], best: bool) -> Option<Cell> {
    let parts: Vec<&EvalSummary> = evals
        .iter()
        .filter_map(|e| {
            if best {
                e.best_checkpoint.as_ref()
            } else {
                Some(&e.final_policy)
            }
        })
        .collect();
    cell_of(&parts)
}

fn cell_of(parts: &[&EvalSummary]) -> Option<Cell> {
    if parts.is_empty() {
        return None;
    }
    let pooled: Vec<f64> = parts
        .iter()
        .flat_map(|p| p.returns.iter().copied())
        .collect();
    let per_seed: Vec<f64> = parts.iter().map(|p| p.mean).collect();
    let (mean, seed_std) = mean_std(&per_seed);
    Some(Cell {
        mean,
        std: mean_std(&pooled).1,
        seed_std,
        seeds: parts.len(),
        episodes: pooled.len(),
        per_seed,
        steps: parts.iter().map(|p| p.env_steps).max().unwrap_or(0),
    })
}

/// One seed: mean ± std over its episodes; more: mean ± std across the
/// seeds' means, with each seed's mean.
fn fmt_cell(c: &Option<Cell>, missing: usize) -> String {
    match c {
        None => "not run".into(),
        Some(c) => {
            let mut s = if c.seeds > 1 {
                let each: Vec<String> = c.per_seed.iter().map(|x| format!("{x:.1}")).collect();
                format!(
                    "{:.2} ± {:.2} ({} seeds: {})",
                    c.mean,
                    c.seed_std,
                    c.seeds,
                    each.join(", ")
                )
            } else {
                format!("{:.2} ± {:.2}", c.mean, c.std)
            };
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
        .map_while(std::result::Result::ok)
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

fn report(root: &Path, cfg: &TableConfig) -> Result<(String, String)> {
    let (envs, methods, seeds) = (&cfg.envs, &cfg.methods, &cfg.seeds);
    let experts_dir = cfg.experts_dir();
    let mut evals: BTreeMap<(usize, usize), Vec<EvalFile>> = BTreeMap::new();
    for (ei, &env) in envs.iter().enumerate() {
        for (mi, &m) in methods.iter().enumerate() {
            for &seed in seeds {
                let dir =
                    root.join("runs")
                        .join(format!("{}-{}-s{seed}", short_name(env), m.name()));
                if let Some(e) = run::read_eval(&dir) {
                    evals.entry((ei, mi)).or_default().push(e);
                }
            }
        }
    }
    let experts: Vec<Option<(EvalFile, f64, f64)>> = envs
        .iter()
        .map(|&env| {
            let e = run::read_eval(&expert_dir(experts_dir, env))?;
            let chosen = match e.expert_choice.as_deref() {
                Some("best checkpoint") => e.best_checkpoint.clone()?,
                _ => e.final_policy.clone(),
            };
            Some((e, chosen.mean, chosen.std))
        })
        .collect();

    let mut md = String::new();
    md.push_str(&format!(
        "Grid `{}`: TRPO budget {} env steps per run; seeds {:?}; {} evaluation episodes per run (deterministic actions, true reward). A cell of one seed is the mean ± std over its episodes; a cell of several is the mean ± std across the seeds' means, each seed's mean in parentheses; in `table.csv`, `mean` is the mean of the seeds' means, `std` the pooled std over every episode and `std_across_seeds` the std of the seeds' means (0 for one seed).\n\n",
        cfg.name, cfg.steps, seeds, cfg.eval_episodes
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
    let mut csv = String::from(
        "env,method,protocol,seeds,episodes,mean,std,per_seed_means,env_steps,std_across_seeds\n",
    );
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
                        "{},{},{},{},{},{},{},{},{},{}\n",
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
                        c.steps,
                        c.seed_std
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

#[cfg(test)]
mod tests {
    use super::*;

    fn summary(returns: &[f64]) -> EvalSummary {
        let (mean, std) = mean_std(returns);
        EvalSummary {
            protocol: "final".into(),
            env_steps: 1000,
            mean,
            std,
            mean_length: 1000.0,
            returns: returns.to_vec(),
        }
    }

    #[test]
    fn a_cell_of_several_seeds_shows_the_spread_across_the_seeds_means() {
        // Two seeds whose episodes are steady (std 1 within each) but whose
        // means differ by 100: the spread across seeds is 50, the pooled
        // spread over episodes 47.15 (the six episodes pooled), and one seed's cell keeps
        // its own episodes' std.
        let a = summary(&[99.0, 101.0]);
        let b = summary(&[199.0, 201.0, 199.0, 201.0]);
        let c = cell_of(&[&a, &b]).unwrap();
        assert_eq!(c.seeds, 2);
        assert_eq!(c.episodes, 6);
        assert!((c.mean - 150.0).abs() < 1e-9, "mean of the seeds' means");
        assert!((c.seed_std - 50.0).abs() < 1e-9);
        assert!((c.std - 47.15).abs() < 0.01, "pooled std {}", c.std);
        let text = fmt_cell(&Some(c), 1);
        assert!(
            text.starts_with("150.00 ± 50.00 (2 seeds: 100.0, 200.0)"),
            "{text}"
        );
        assert!(text.ends_with("[partial: 1 seed(s) missing]"), "{text}");

        let one = cell_of(&[&a]).unwrap();
        assert_eq!(fmt_cell(&Some(one), 0), "100.00 ± 1.00");
        assert!(cell_of(&[]).is_none());
    }
}
