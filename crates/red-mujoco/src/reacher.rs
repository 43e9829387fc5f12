//! Reacher: a two-joint arm that must bring its fingertip to a target,
//! Gymnasium's `Reacher-v5`.

use red_core::{Env, Info, Space, Step};
use serde::{Deserialize, Serialize};

use crate::common::{EnvCore, MujocoEnv, info_template, sum_of_squares, uniform, validate};
use crate::{Result, Simulation};

/// Settings of [`Reacher`]. Every default is Gymnasium 1.x's `Reacher-v5`
/// default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReacherConfig {
    /// Model file in the assets folder (`reacher.xml`).
    pub xml_file: String,
    /// Physics steps per environment step (2; 0.02 s per step).
    pub frame_skip: usize,
    /// Weight of the fingertip-target distance in the reward (1).
    pub reward_dist_weight: f64,
    /// Weight of the squared action in the reward (1).
    pub reward_control_weight: f64,
}

impl Default for ReacherConfig {
    fn default() -> Self {
        Self {
            xml_file: "reacher.xml".into(),
            frame_skip: 2,
            reward_dist_weight: 1.0,
            reward_control_weight: 1.0,
        }
    }
}

impl ReacherConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`crate::Error::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        validate::xml_file(&self.xml_file)?;
        validate::frame_skip(self.frame_skip)?;
        validate::finite("reward_dist_weight", self.reward_dist_weight)?;
        validate::finite("reward_control_weight", self.reward_control_weight)
    }
}

const INFO_KEYS: [&str; 2] = ["reward_dist", "reward_ctrl"];

/// Gymnasium's `Reacher-v5`.
///
/// - Observation (10): cos and sin of the two joint angles, the target's
///   position `qpos[2..4]`, the joint velocities `qvel[..2]`, and the x, y
///   of fingertip minus target.
/// - Action: 2 torques in [-1, 1].
/// - Reward: `-reward_dist_weight * |fingertip - target| -
///   reward_control_weight * |a|^2` (the distance in 3D, from the bodies'
///   `xpos`); info holds `reward_dist` and `reward_ctrl`.
/// - Never terminates; Gymnasium's time limit is 50 steps.
/// - Reset: joint angles `qpos0 + U[-0.1, 0.1)`, a target drawn from
///   `U[-0.2, 0.2)^2` until it lies inside the disc of radius 0.2, arm
///   velocities `U[-0.005, 0.005)`, target velocity 0.
#[derive(Debug)]
pub struct Reacher {
    config: ReacherConfig,
    core: EnvCore,
    info: Info,
    fingertip: usize,
    target: usize,
}

impl Reacher {
    /// Loads the model and builds the environment.
    ///
    /// # Errors
    /// A rejected config, or a model that cannot be loaded (run
    /// `scripts/setup-mujoco.sh`) or lacks the `fingertip` and `target`
    /// bodies.
    pub fn new(config: ReacherConfig) -> Result<Self> {
        config.validate()?;
        let sim = Simulation::load(&config.xml_file, config.frame_skip)?;
        let fingertip = sim.body_id("fingertip")?;
        let target = sim.body_id("target")?;
        if sim.nq() < 4 || sim.nv() < 2 {
            return Err(crate::Error::ModelMismatch {
                model: sim.name().to_string(),
                reason: format!(
                    "need two arm joints and a 2D target, got nq = {}, nv = {}",
                    sim.nq(),
                    sim.nv()
                ),
            });
        }
        let obs_dim = 4 + (sim.nq() - 2) + 2 + 2;
        Ok(Self {
            core: EnvCore::new(sim, obs_dim)?,
            info: info_template(&INFO_KEYS),
            config,
            fingertip,
            target,
        })
    }

    /// The settings.
    pub fn config(&self) -> &ReacherConfig {
        &self.config
    }

    /// Fingertip minus target, from the bodies' frame positions.
    fn fingertip_to_target(&self) -> [f64; 3] {
        let f = self.core.sim.body_xpos(self.fingertip);
        let t = self.core.sim.body_xpos(self.target);
        [f[0] - t[0], f[1] - t[1], f[2] - t[2]]
    }
}

impl MujocoEnv for Reacher {
    fn simulation(&self) -> &Simulation {
        &self.core.sim
    }

    fn set_state(&mut self, qpos: &[f64], qvel: &[f64]) -> red_core::Result<Vec<f64>> {
        self.core.sim.set_state(qpos, qvel)?;
        self.core.needs_reset = false;
        Ok(self.observation())
    }

    fn observation(&self) -> Vec<f64> {
        let sim = &self.core.sim;
        let (qpos, qvel) = (sim.qpos(), sim.qvel());
        let d = self.fingertip_to_target();
        let mut obs = Vec::with_capacity(self.core.observation_space.dim());
        obs.extend(qpos[..2].iter().map(|t| t.cos()));
        obs.extend(qpos[..2].iter().map(|t| t.sin()));
        obs.extend_from_slice(&qpos[2..]);
        obs.extend_from_slice(&qvel[..2]);
        obs.extend_from_slice(&d[..2]);
        obs
    }
}

impl Env for Reacher {
    fn observation_space(&self) -> &Space {
        &self.core.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.core.action_space
    }

    fn reset(&mut self, seed: Option<u64>) -> red_core::Result<(Vec<f64>, Info)> {
        self.core.begin_reset(seed);
        let sim = &self.core.sim;
        let (init_qpos, init_qvel) = (sim.init_qpos().to_vec(), sim.init_qvel().to_vec());
        let mut qpos = self.core.add_uniform(&init_qpos, -0.1, 0.1);
        let goal = loop {
            let g = [
                uniform(&mut self.core.rng, -0.2, 0.2),
                uniform(&mut self.core.rng, -0.2, 0.2),
            ];
            if g[0].hypot(g[1]) < 0.2 {
                break g;
            }
        };
        let nq = qpos.len();
        qpos[nq - 2..].copy_from_slice(&goal);
        let mut qvel = self.core.add_uniform(&init_qvel, -0.005, 0.005);
        let nv = qvel.len();
        qvel[nv - 2..].fill(0.0);
        let obs = self.set_state(&qpos, &qvel)?;
        Ok((obs, Info::new()))
    }

    fn step(&mut self, action: &[f64]) -> red_core::Result<Step> {
        self.core.check_step(action)?;
        self.core.sim.step(action)?;
        let observation = self.observation();
        let d = self.fingertip_to_target();
        let dist = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let reward_dist = -dist * self.config.reward_dist_weight;
        let reward_ctrl = -sum_of_squares(action) * self.config.reward_control_weight;
        let mut info = self.info.clone();
        info.set("reward_dist", reward_dist);
        info.set("reward_ctrl", reward_ctrl);
        Ok(Step {
            observation,
            reward: reward_dist + reward_ctrl,
            terminated: false,
            truncated: false,
            info,
        })
    }
}
