//! Walker2d: a two-legged planar robot that must walk forward, Gymnasium's
//! `Walker2d-v5`.

use red_core::{Env, Info, Space, Step};
use serde::{Deserialize, Serialize};

use crate::common::{EnvCore, MujocoEnv, info_template, range_serde, sum_of_squares, validate};
use crate::{Result, Simulation};

/// Settings of [`Walker2d`]. Every default is Gymnasium 1.x's `Walker2d-v5`
/// default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Walker2dConfig {
    /// Model file in the assets folder (`walker2d_v5.xml`: both feet with
    /// friction 1.9, where the older `walker2d.xml` gives the right foot
    /// 0.9).
    pub xml_file: String,
    /// Physics steps per environment step (4; 0.008 s per step).
    pub frame_skip: usize,
    /// Weight of the forward velocity in the reward (1).
    pub forward_reward_weight: f64,
    /// Weight of the squared action in the control cost (0.001).
    pub ctrl_cost_weight: f64,
    /// Reward per step while healthy (1).
    pub healthy_reward: f64,
    /// End the episode (terminated) when the robot becomes unhealthy (true).
    pub terminate_when_unhealthy: bool,
    /// Open interval of the torso height `qpos[1]` (0.8, 2).
    #[serde(with = "range_serde")]
    pub healthy_z_range: [f64; 2],
    /// Open interval of the torso angle `qpos[2]` (-1, 1).
    #[serde(with = "range_serde")]
    pub healthy_angle_range: [f64; 2],
    /// Half-width of the uniform noise added to positions and velocities at
    /// reset (0.005).
    pub reset_noise_scale: f64,
    /// Leave the x position `qpos[0]` out of the observation (true: 17
    /// numbers, else 18).
    pub exclude_current_positions_from_observation: bool,
}

impl Default for Walker2dConfig {
    fn default() -> Self {
        Self {
            xml_file: "walker2d_v5.xml".into(),
            frame_skip: 4,
            forward_reward_weight: 1.0,
            ctrl_cost_weight: 1e-3,
            healthy_reward: 1.0,
            terminate_when_unhealthy: true,
            healthy_z_range: [0.8, 2.0],
            healthy_angle_range: [-1.0, 1.0],
            reset_noise_scale: 5e-3,
            exclude_current_positions_from_observation: true,
        }
    }
}

impl Walker2dConfig {
    /// Checks every field.
    ///
    /// # Errors
    /// [`crate::Error::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        validate::xml_file(&self.xml_file)?;
        validate::frame_skip(self.frame_skip)?;
        validate::finite("forward_reward_weight", self.forward_reward_weight)?;
        validate::finite("ctrl_cost_weight", self.ctrl_cost_weight)?;
        validate::finite("healthy_reward", self.healthy_reward)?;
        validate::range("healthy_z_range", self.healthy_z_range)?;
        validate::range("healthy_angle_range", self.healthy_angle_range)?;
        validate::non_negative("reset_noise_scale", self.reset_noise_scale)
    }
}

const INFO_KEYS: [&str; 6] = [
    "x_position",
    "z_distance_from_origin",
    "x_velocity",
    "reward_forward",
    "reward_ctrl",
    "reward_survive",
];

/// Gymnasium's `Walker2d-v5`.
///
/// - Observation: `qpos[1..]` (8) then `qvel` clipped to [-10, 10] (9).
/// - Action: 6 torques in [-1, 1].
/// - Reward: `forward_reward_weight * x_velocity + healthy_reward *
///   is_healthy - ctrl_cost_weight * |a|^2`; info holds `reward_forward`,
///   `reward_ctrl` (negative), `reward_survive`, `x_position`,
///   `x_velocity`, `z_distance_from_origin`.
/// - Terminated when unhealthy (see [`Walker2dConfig`]); no time limit here
///   (Gymnasium's is 1000 steps, see [`crate::EnvId::max_episode_steps`]).
/// - Reset: `qpos0` and zero velocities plus `U[-0.005, 0.005)` noise.
#[derive(Debug)]
pub struct Walker2d {
    config: Walker2dConfig,
    core: EnvCore,
    info: Info,
}

impl Walker2d {
    /// Loads the model and builds the environment.
    ///
    /// # Errors
    /// A rejected config, or a model that cannot be loaded (run
    /// `scripts/setup-mujoco.sh`).
    pub fn new(config: Walker2dConfig) -> Result<Self> {
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
    pub fn config(&self) -> &Walker2dConfig {
        &self.config
    }

    /// Whether the current state is healthy: torso height and angle inside
    /// their open intervals.
    pub fn is_healthy(&self) -> bool {
        let qpos = self.core.sim.qpos();
        let (z, angle) = (qpos[1], qpos[2]);
        let [min_z, max_z] = self.config.healthy_z_range;
        let [min_a, max_a] = self.config.healthy_angle_range;
        min_z < z && z < max_z && min_a < angle && angle < max_a
    }

    fn write_observation(&self, out: &mut Vec<f64>) {
        let sim = &self.core.sim;
        let skip = usize::from(self.config.exclude_current_positions_from_observation);
        out.extend_from_slice(&sim.qpos()[skip..]);
        out.extend(sim.qvel().iter().map(|v| v.clamp(-10.0, 10.0)));
    }

    fn position_info(&self, info: &mut Info) {
        let sim = &self.core.sim;
        info.set("x_position", sim.qpos()[0]);
        info.set("z_distance_from_origin", sim.qpos()[1] - sim.init_qpos()[1]);
    }
}

impl MujocoEnv for Walker2d {
    fn simulation(&self) -> &Simulation {
        &self.core.sim
    }

    fn set_state(&mut self, qpos: &[f64], qvel: &[f64]) -> red_core::Result<Vec<f64>> {
        self.core.sim.set_state(qpos, qvel)?;
        self.core.needs_reset = false;
        Ok(self.observation())
    }

    fn observation(&self) -> Vec<f64> {
        let mut obs = Vec::with_capacity(self.core.observation_space.dim());
        self.write_observation(&mut obs);
        obs
    }
}

impl Env for Walker2d {
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
        let qvel = self.core.add_uniform(&init_qvel, -s, s);
        let obs = self.set_state(&qpos, &qvel)?;
        let mut info = Info::new();
        self.position_info(&mut info);
        Ok((obs, info))
    }

    fn step(&mut self, action: &[f64]) -> red_core::Result<Step> {
        self.core.check_step(action)?;
        let x_before = self.core.sim.qpos()[0];
        self.core.sim.step(action)?;
        let x_after = self.core.sim.qpos()[0];
        let x_velocity = (x_after - x_before) / self.core.sim.dt();
        let observation = self.observation();

        let healthy = self.is_healthy();
        let forward_reward = self.config.forward_reward_weight * x_velocity;
        let healthy_reward = if healthy {
            self.config.healthy_reward
        } else {
            0.0
        };
        let ctrl_cost = self.config.ctrl_cost_weight * sum_of_squares(action);
        let reward = forward_reward + healthy_reward - ctrl_cost;
        let terminated = !healthy && self.config.terminate_when_unhealthy;
        self.core.needs_reset = terminated;

        let mut info = self.info.clone();
        self.position_info(&mut info);
        info.set("x_velocity", x_velocity);
        info.set("reward_forward", forward_reward);
        info.set("reward_ctrl", -ctrl_cost);
        info.set("reward_survive", healthy_reward);
        Ok(Step {
            observation,
            reward,
            terminated,
            truncated: false,
            info,
        })
    }
}
