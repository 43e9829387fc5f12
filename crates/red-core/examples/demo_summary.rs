//! Reads a demonstration file (validated on the way in) and prints what it
//! holds: `cargo run -p red-core --example demo_summary [FILE]`.
use red_core::Demos;

fn main() -> red_core::Result<()> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "data/drive-scripted-expert.json".into());
    let demos = Demos::read(path.as_ref())?;
    println!("{}", demos.summary());
    let (states, actions) = demos.pairs();
    println!(
        "pairs: states {:?}, actions {:?}; made by {:?}",
        states.dim(),
        actions.dim(),
        demos.source
    );
    Ok(())
}
