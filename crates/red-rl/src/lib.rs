//! Learners of the red workspace: DQN, TRPO, SVG(1)-ER, SAC, behaviour cloning,
//! and the imitation baselines whose reward adapts during training, GAIL and
//! GMMIL. Learners are generic over [`red_core::Env`] and take any
//! [`red_core::RewardModel`].

pub mod bc;
pub mod dqn;
pub mod episodic;
pub mod error;
pub mod gae;
pub mod gail;
pub mod gmmil;
pub mod normalize;
pub mod policy;
pub mod replay;
pub mod rollout;
pub mod sac;
pub mod svg;
pub mod trpo;

pub use error::{Error, Result};

// The exact versions of the crates this crate's API takes and returns,
// so that a dependant names the same types (a second version of ndarray or
// rand in a build gives type errors that never mention versions).
pub use ndarray;
pub use rand;
pub use rand_chacha;
