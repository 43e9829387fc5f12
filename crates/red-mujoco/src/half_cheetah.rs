//! HalfCheetah: a planar two-legged runner, Gymnasium's `HalfCheetah-v5`.

use red_core::{Env, Info, Space, Step};
use serde::{Deserialize, Serialize};

use crate::common::{EnvCore, MujocoEnv, info_template, sum_of_squares, validate};
use crate::{Result, Simulation};

/// Settings of [`HalfCheetah`]. Every default is Gymnasium 1.x's
/// `HalfCheetah-v5` default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HalfCheetahConfig {
    /// Model file in the assets folder (`half_cheetah.xml`).
    pub xml_file: String,
    /// Physics steps per environment step (5; 0.05 s per step).
    pub frame_skip: usize,
    /// Weight of the forward velocity in the reward (1).
    pub forward_reward_weight: f64,
    /// Weight of the squared action in the control cost (0.1).
    pub ctrl_cost_weight: f64,
    /// Scale of the reset noise (0.1): half-width of the uniform noise on
    /// positions, standard deviation of the normal noise on velocities.
    pub reset_noise_scale: f64,
    /// Leave the x position `qpos[0]` out of the observation (true: 17
    /// numbers, else 18).
    pub exclude_current_positions_from_observation: bool,
}

impl Default for HalfCheetahConfig {
    fn default() -> Self {
        Self {
            xml_file: "half_cheetah.xml".into(),
            frame_skip: 5,
            forward_reward_weight: 1.0,
            ctrl_cost_weight: 0.1,
            reset_noise_scale: 0.1,
            exclude_current_positions_from_observation: true,
        }
    }
}

impl HalfCheetahConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`crate::Error::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        validate::xml_file(&self.xml_file)?;
        validate::frame_skip(self.frame_skip)?;
        validate::finite("forward_reward_weight", self.forward_reward_weight)?;
        validate::finite("ctrl_cost_weight", self.ctrl_cost_weight)?;
        validate::non_negative("reset_noise_scale", self.reset_noise_scale)
    }
}

const INFO_KEYS: [&str; 4] = ["x_position", "x_velocity", "reward_forward", "reward_ctrl"];

/// Gymnasium's `HalfCheetah-v5`.
///
/// - Observation: `qpos[1..]` (8) then `qvel` (9).
/// - Action: 6 torques in [-1, 1].
/// - Reward: `forward_reward_weight * x_velocity - ctrl_cost_weight *
///   |a|^2`; info holds `reward_forward`, `reward_ctrl` (negative),
///   `x_position`, `x_velocity`.
/// - Never terminates; Gymnasium's time limit is 1000 steps.
/// - Reset: `qpos0` plus `U[-0.1, 0.1)` noise, zero velocities plus
///   `0.1 * N(0, 1)` noise.
#[derive(Debug)]
pub struct HalfCheetah {
    config: HalfCheetahConfig,
    core: EnvCore,
    info: Info,
}

impl HalfCheetah {
    /// Loads the model and builds the environment.
    ///
    /// # Errors
    /// A rejected config, or a model that cannot be loaded (run
    /// `scripts/setup-mujoco.sh`).
    pub fn new(config: HalfCheetahConfig) -> Result<Self> {
        config.validate()?;
        let sim = Simulation::load(&config.xml_file, config.frame_skip)?;
        let skip = usize::from(config.exclude_current_positions_from_observation);
        let obs_dim = sim.nq() + sim.nv() - skip;
        Ok(Self {
            core: EnvCore::new(sim, obs_dim)?,
            info: info_template(&INFO_KEYS),
            config,
        })
    }

    /// The settings.
    pub fn config(&self) -> &HalfCheetahConfig {
        &self.config
    }
}

impl MujocoEnv for HalfCheetah {
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
        let skip = usize::from(self.config.exclude_current_positions_from_observation);
        let mut obs = Vec::with_capacity(self.core.observation_space.dim());
        obs.extend_from_slice(&sim.qpos()[skip..]);
        obs.extend_from_slice(sim.qvel());
        obs
    }
}

impl Env for HalfCheetah {
    fn observation_space(&self) -> &Space {
        &self.core.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.core.action_space
    }

    fn reset(&mut self, seed: Option<u64>) -> red_core::Result<(Vec<f64>, Info)> {
        self.core.begin_reset(seed);
        let s = self.config.reset_noise_scale;
        let sim = &self.core.sim;
        let (init_qpos, init_qvel) = (sim.init_qpos().to_vec(), sim.init_qvel().to_vec());
        let qpos = self.core.add_uniform(&init_qpos, -s, s);
        let qvel = self.core.add_normal(&init_qvel, s);
        let obs = self.set_state(&qpos, &qvel)?;
        let mut info = Info::new();
        info.set("x_position", self.core.sim.qpos()[0]);
        Ok((obs, info))
    }

    fn step(&mut self, action: &[f64]) -> red_core::Result<Step> {
        self.core.check_step(action)?;
        let x_before = self.core.sim.qpos()[0];
        self.core.sim.step(action)?;
        let x_after = self.core.sim.qpos()[0];
        let x_velocity = (x_after - x_before) / self.core.sim.dt();
        let observation = self.observation();

        let forward_reward = self.config.forward_reward_weight * x_velocity;
        let ctrl_cost = self.config.ctrl_cost_weight * sum_of_squares(action);
        let reward = forward_reward - ctrl_cost;

        let mut info = self.info.clone();
        info.set("x_position", x_after);
        info.set("x_velocity", x_velocity);
        info.set("reward_forward", forward_reward);
        info.set("reward_ctrl", -ctrl_cost);
        Ok(Step {
            observation,
            reward,
            terminated: false,
            truncated: false,
            info,
        })
    }
}
