//! Diagnosis: a finished run's final policy acting by lookahead through
//! the learner it kept (`{"keep_learner": true}` in `--train-config`): at
//! each step the policy's action and the candidates around it are scored
//! by `r(s, a) + gamma^H V(x_H)` through the learned model and value, and
//! the best is driven. Prints `eval_saved`'s lines for each run folder.
//! `cargo run --release -p red-experiments --example drive_lookahead --
//! [--steer -0.1,-0.05,0.05,0.1] [--pedal 0.1] [--horizon 1]
//! [--value-only] [--current-policy] [--method red] RUN_DIR...`
use red_experiments::drive::{EvalRequest, Lookahead, eval_saved};

fn offsets(v: Option<String>) -> Result<Vec<f64>, Box<dyn std::error::Error>> {
    let v = v.ok_or("--steer and --pedal take comma-separated numbers")?;
    Ok(v.split(',')
        .map(|x| x.trim().parse())
        .collect::<Result<_, _>>()?)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut ask = Lookahead {
        steer: vec![-0.1, -0.05, 0.05, 0.1],
        horizon: 1,
        ..Lookahead::default()
    };
    let mut dirs = Vec::new();
    let mut method = "red".to_string();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--steer" => ask.steer = offsets(args.next())?,
            "--pedal" => ask.pedal = offsets(args.next())?,
            "--horizon" => ask.horizon = args.next().ok_or("--horizon takes a number")?.parse()?,
            "--value-only" => ask.value_only = true,
            "--current-policy" => ask.current_policy = true,
            "--method" => method = args.next().ok_or("--method takes red, ae, gail or gmmil")?,
            _ => dirs.push(std::path::PathBuf::from(a)),
        }
    }
    if dirs.is_empty() {
        return Err(
            "usage: drive_lookahead [--steer A,B] [--pedal A,B] [--horizon H] \
                    [--value-only] [--current-policy] [--method M] RUN_DIR..."
                .into(),
        );
    }
    for dir in dirs {
        let req = EvalRequest {
            method: method.clone(),
            lookahead: Some(ask.clone()),
            ..EvalRequest::default()
        };
        println!("== {}\n{}", dir.display(), eval_saved(&dir, &req)?);
    }
    Ok(())
}
