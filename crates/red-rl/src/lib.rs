//! Learners of the red workspace.
//!
//! Status: this crate is a placeholder of the workspace. DQN, TRPO, SVG(1)-ER,
//! behaviour cloning, GAIL and GMMIL come with later issues; until then it
//! provides nothing.
