//! Ant: a four-legged robot walking in 3D, Gymnasium's `Ant-v5`.

use red_core::{Env, Info, Space, Step};
use serde::{Deserialize, Serialize};

use crate::common::{EnvCore, MujocoEnv, info_template, range_serde, sum_of_squares, validate};
use crate::{Error, Result, Simulation};

/// Settings of [`Ant`]. Every default is Gymnasium 1.x's `Ant-v5` default
/// except one, `include_cfrc_ext_in_observation`, said below.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AntConfig {
    /// Model file in the assets folder (`ant.xml`).
    pub xml_file: String,
    /// Physics steps per environment step (5; 0.05 s per step).
    pub frame_skip: usize,
    /// Weight of the forward (x) velocity in the reward (1).
    pub forward_reward_weight: f64,
    /// Weight of the squared action in the control cost (0.5).
    pub ctrl_cost_weight: f64,
    /// Weight of the squared clipped contact forces in the contact cost
    /// (5e-4).
    pub contact_cost_weight: f64,
    /// Reward per step while healthy (1).
    pub healthy_reward: f64,
    /// Id of the body whose frame position gives the velocity (1, the
    /// torso).
    pub main_body: usize,
    /// End the episode (terminated) when the robot becomes unhealthy (true).
    pub terminate_when_unhealthy: bool,
    /// Closed interval of the torso height `qpos[2]` (0.2, 1).
    #[serde(with = "range_serde")]
    pub healthy_z_range: [f64; 2],
    /// Interval the contact forces are clipped to, in the cost and the
    /// observation (-1, 1).
    #[serde(with = "range_serde")]
    pub contact_force_range: [f64; 2],
    /// Scale of the reset noise (0.1): half-width of the uniform noise on
    /// positions, standard deviation of the normal noise on velocities.
    pub reset_noise_scale: f64,
    /// Leave the x, y position `qpos[0..2]` out of the observation (true).
    pub exclude_current_positions_from_observation: bool,
    /// Append the clipped contact forces of the 13 bodies (78 numbers) to
    /// the observation. Default false (27 numbers, as Gymnasium's `Ant-v4`
    /// and `Ant-v5` with this option off); Gymnasium's `Ant-v5` default is
    /// true (105 numbers). The reward includes the contact cost either way.
    pub include_cfrc_ext_in_observation: bool,
}

impl Default for AntConfig {
    fn default() -> Self {
        Self {
            xml_file: "ant.xml".into(),
            frame_skip: 5,
            forward_reward_weight: 1.0,
            ctrl_cost_weight: 0.5,
            contact_cost_weight: 5e-4,
            healthy_reward: 1.0,
            main_body: 1,
            terminate_when_unhealthy: true,
            healthy_z_range: [0.2, 1.0],
            contact_force_range: [-1.0, 1.0],
            reset_noise_scale: 0.1,
            exclude_current_positions_from_observation: true,
            include_cfrc_ext_in_observation: false,
        }
    }
}

impl AntConfig {
    /// Checks every field (the model-dependent `main_body` is checked when
    /// the environment is built).
    ///
    /// # Errors
    /// [`crate::Error::InvalidConfig`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        validate::xml_file(&self.xml_file)?;
        validate::frame_skip(self.frame_skip)?;
        validate::finite("forward_reward_weight", self.forward_reward_weight)?;
        validate::finite("ctrl_cost_weight", self.ctrl_cost_weight)?;
        validate::finite("contact_cost_weight", self.contact_cost_weight)?;
        validate::finite("healthy_reward", self.healthy_reward)?;
        validate::range("healthy_z_range", self.healthy_z_range)?;
        validate::range("contact_force_range", self.contact_force_range)?;
        validate::non_negative("reset_noise_scale", self.reset_noise_scale)
    }
}

const INFO_KEYS: [&str; 9] = [
    "x_position",
    "y_position",
    "distance_from_origin",
    "x_velocity",
    "y_velocity",
    "reward_forward",
    "reward_ctrl",
    "reward_contact",
    "reward_survive",
];

/// Gymnasium's `Ant-v5`.
///
/// - Observation: `qpos[2..]` (13), `qvel` (14), and with
///   [`AntConfig::include_cfrc_ext_in_observation`] the contact forces
///   `cfrc_ext[1..]` clipped to [-1, 1] (78).
/// - Action: 8 torques in [-1, 1].
/// - Reward: `forward_reward_weight * x_velocity + healthy_reward *
///   is_healthy - ctrl_cost_weight * |a|^2 - contact_cost_weight *
///   |clip(cfrc_ext)|^2`, the velocity from the torso frame's `xpos`; info
///   holds `reward_forward`, `reward_ctrl`, `reward_contact` (costs
///   negative), `reward_survive`, `x_position`, `y_position`,
///   `distance_from_origin`, `x_velocity`, `y_velocity`.
/// - Terminated when unhealthy: a non-finite state or the torso height
///   outside [0.2, 1]. Gymnasium's time limit is 1000 steps.
/// - Reset: `qpos0` plus `U[-0.1, 0.1)` noise, zero velocities plus
///   `0.1 * N(0, 1)` noise.
#[derive(Debug)]
pub struct Ant {
    config: AntConfig,
    core: EnvCore,
    info: Info,
}

impl Ant {
    /// Loads the model and builds the environment.
    ///
    /// # Errors
    /// A rejected config, a `main_body` the model does not have, or a model
    /// that cannot be loaded (run `scripts/setup-mujoco.sh`).
    pub fn new(config: AntConfig) -> Result<Self> {
        config.validate()?;
        let sim = Simulation::load(&config.xml_file, config.frame_skip)?;
        if config.main_body >= sim.nbody() {
            return Err(Error::InvalidConfig {
                field: "main_body",
                reason: format!(
                    "{} has {} bodies, got id {}",
                    sim.name(),
                    sim.nbody(),
                    config.main_body
                ),
            });
        }
        let skip = 2 * usize::from(config.exclude_current_positions_from_observation);
        let forces = 6 * (sim.nbody() - 1) * usize::from(config.include_cfrc_ext_in_observation);
        let obs_dim = sim.nq() + sim.nv() - skip + forces;
        Ok(Self {
            core: EnvCore::new(sim, obs_dim)?,
            info: info_template(&INFO_KEYS),
            config,
        })
    }

    /// The settings.
    pub fn config(&self) -> &AntConfig {
        &self.config
    }

    /// Whether the current state is healthy: every position and velocity
    /// finite and the torso height `qpos[2]` inside the closed interval.
    pub fn is_healthy(&self) -> bool {
        let sim = &self.core.sim;
        let finite = sim.qpos().iter().chain(sim.qvel()).all(|v| v.is_finite());
        let [min_z, max_z] = self.config.healthy_z_range;
        let z = sim.qpos()[2];
        finite && min_z <= z && z <= max_z
    }

    /// `contact_cost_weight * sum(clip(cfrc_ext)^2)` over every body, the
    /// world included, as Gymnasium computes it.
    pub fn contact_cost(&self) -> f64 {
        let [lo, hi] = self.config.contact_force_range;
        let sum: f64 = self
            .core
            .sim
            .cfrc_ext()
            .iter()
            .flatten()
            .map(|f| {
                let c = f.clamp(lo, hi);
                c * c
            })
            .sum();
        self.config.contact_cost_weight * sum
    }

    fn torso_xy(&self) -> [f64; 2] {
        let p = self.core.sim.body_xpos(self.config.main_body);
        [p[0], p[1]]
    }

    fn position_info(&self, info: &mut Info) {
        let q = self.core.sim.qpos();
        info.set("x_position", q[0]);
        info.set("y_position", q[1]);
        info.set("distance_from_origin", q[0].hypot(q[1]));
    }
}

impl MujocoEnv for Ant {
    fn simulation(&self) -> &Simulation {
        &self.core.sim
    }

    fn set_state(&mut self, qpos: &[f64], qvel: &[f64]) -> red_core::Result<Vec<f64>> {
        // Like Gymnasium, `mj_rnePostConstraint` is not run here: the
        // contact forces in the observation are those left by the last step
        // (zeros right after a reset).
        self.core.sim.set_state(qpos, qvel)?;
        self.core.needs_reset = false;
        Ok(self.observation())
    }

    fn observation(&self) -> Vec<f64> {
        let sim = &self.core.sim;
        let skip = 2 * usize::from(self.config.exclude_current_positions_from_observation);
        let mut obs = Vec::with_capacity(self.core.observation_space.dim());
        obs.extend_from_slice(&sim.qpos()[skip..]);
        obs.extend_from_slice(sim.qvel());
        if self.config.include_cfrc_ext_in_observation {
            let [lo, hi] = self.config.contact_force_range;
            obs.extend(
                sim.cfrc_ext()[1..]
                    .iter()
                    .flatten()
                    .map(|f| f.clamp(lo, hi)),
            );
        }
        obs
    }
}

impl Env for Ant {
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
        self.position_info(&mut info);
        Ok((obs, info))
    }

    fn step(&mut self, action: &[f64]) -> red_core::Result<Step> {
        self.core.check_step(action)?;
        let before = self.torso_xy();
        self.core.sim.step_with_contact_forces(action)?;
        let after = self.torso_xy();
        let dt = self.core.sim.dt();
        let x_velocity = (after[0] - before[0]) / dt;
        let y_velocity = (after[1] - before[1]) / dt;
        let observation = self.observation();

        let healthy = self.is_healthy();
        let forward_reward = x_velocity * self.config.forward_reward_weight;
        let healthy_reward = if healthy {
            self.config.healthy_reward
        } else {
            0.0
        };
        let ctrl_cost = self.config.ctrl_cost_weight * sum_of_squares(action);
        let contact_cost = self.contact_cost();
        let reward = (forward_reward + healthy_reward) - (ctrl_cost + contact_cost);
        let terminated = !healthy && self.config.terminate_when_unhealthy;
        self.core.needs_reset = terminated;

        let mut info = self.info.clone();
        self.position_info(&mut info);
        info.set("x_velocity", x_velocity);
        info.set("y_velocity", y_velocity);
        info.set("reward_forward", forward_reward);
        info.set("reward_ctrl", -ctrl_cost);
        info.set("reward_contact", -contact_cost);
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
