//! The root package of the `red` workspace. It holds no code of its own: its
//! `tests/` folder holds the end-to-end tests that drive several crates (and
//! the `red-cli` binary) together.
