//! Drives finished runs' saved final RED policies again (the evaluation's
//! episodes: the demo's road and the unseen roads) and prints each road's
//! % and how every episode ended, through
//! [`red_experiments::drive::eval_saved`]; last, the counts of endings
//! (finish / crash / time up) over all the runs given, on the demo's road
//! and on the unseen roads, and the crashes before 100 m by the episode's
//! reset seed (1000, 1001, ...) over all roads.
//! `--runs N` drives N episodes per road instead of the evaluation's 5
//! (reset seeds 1000, 1001, ...: the first 5 are the evaluation's);
//! `--roads S,S,..` drives those track seeds instead of the run's roads;
//! `--png FILE` draws the first road's episodes.
//! `cargo run --release -p red-experiments --example drive_eval_saved --
//! [--runs N] [--roads S,S,..] [--png FILE] RUN_DIR...`
use red_experiments::drive::{EvalRequest, eval_saved};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    const USAGE: &str =
        "usage: drive_eval_saved [--runs N] [--roads S,S,..] [--png FILE] RUN_DIR...";
    let mut req = EvalRequest {
        method: "red".into(),
        ..EvalRequest::default()
    };
    let mut runs: Vec<String> = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--runs" => {
                let v = args.next().ok_or(USAGE)?;
                req.runs = Some(v.parse().map_err(|e| format!("--runs {v}: {e}"))?);
            }
            "--roads" => {
                let v = args.next().ok_or(USAGE)?;
                req.roads = v
                    .split(',')
                    .map(|s| s.trim().parse().map_err(|e| format!("--roads {v}: {e}")))
                    .collect::<Result<_, _>>()?;
            }
            "--png" => req.png = Some(args.next().ok_or(USAGE)?.into()),
            flag if flag.starts_with("--") => {
                return Err(format!("unknown option {flag}; {USAGE}").into());
            }
            _ => runs.push(a),
        }
    }
    if runs.is_empty() {
        return Err(USAGE.into());
    }
    if req.png.is_some() && runs.len() > 1 {
        return Err("--png draws one run folder's episodes; give one folder".into());
    }
    // [finish, crash, time up] on the demo's road and on unseen roads.
    let (mut demo, mut unseen) = ([0usize; 3], [0usize; 3]);
    // Crashes before 100 m, by the episode's place in the road's line
    // (its reset seed is 1000 + place).
    let mut early: Vec<usize> = Vec::new();
    for d in &runs {
        println!("== {d}");
        let out = eval_saved(std::path::Path::new(d), &req)?;
        print!("{out}");
        for line in out.lines().filter(|l| l.starts_with("road ")) {
            let c = if line.contains("demonstration") {
                &mut demo
            } else {
                &mut unseen
            };
            for (k, word) in ["finish", "crash", "time up"].iter().enumerate() {
                c[k] += line.matches(word).count();
            }
            // "road N: P% | D ending | D ending ..."
            for (i, ep) in line.split(" | ").skip(1).enumerate() {
                let d: f64 = ep.split_whitespace().next().unwrap_or("").parse()?;
                if early.len() <= i {
                    early.resize(i + 1, 0);
                }
                if ep.contains("crash") && d < 100.0 {
                    early[i] += 1;
                }
            }
        }
    }
    println!(
        "{} run(s), finish / crash / time up: demo's road {} / {} / {}, unseen roads {} / {} / {}",
        runs.len(),
        demo[0],
        demo[1],
        demo[2],
        unseen[0],
        unseen[1],
        unseen[2]
    );
    let by_seed: Vec<String> = early
        .iter()
        .enumerate()
        .map(|(i, n)| format!("{} {n}", 1000 + i))
        .collect();
    println!(
        "crashes before 100 m by reset seed (all roads): {}",
        by_seed.join(", ")
    );
    Ok(())
}
