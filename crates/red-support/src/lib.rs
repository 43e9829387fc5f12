//! Support estimation of the expert policy and RED's reward.
//!
//! Status: this crate is a placeholder of the workspace. Its content (RND,
//! autoencoder and kernel PCA support estimators, `RedReward`, the terminal
//! reward heuristic) comes with the issue "Support estimation and RED's
//! reward"; until then it provides nothing.
