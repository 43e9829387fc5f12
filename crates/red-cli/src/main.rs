//! `red-cli`: the command-line tool of the red workspace.

fn main() {
    println!("red-cli: no subcommands yet");
}
