//! MuJoCo environments (Hopper, HalfCheetah, Walker2d, Ant, Reacher).
//!
//! Status: this crate is a placeholder of the workspace. The environments come
//! with the issue "MuJoCo environments, TRPO and expert demonstrations"; until
//! then it provides nothing.
