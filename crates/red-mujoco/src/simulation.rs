//! A MuJoCo model and its data, with the operations the environments need:
//! set the state, apply a control for `frame_skip` physics steps, read
//! positions, velocities and contact forces.

use std::path::Path;
use std::sync::{Arc, Once};

use mujoco_rs::prelude::{MjData, MjLogMessage, MjModel, MjtLogLevel, MjtObjBase, set_log_handler};

use crate::{Error, Result, assets};

/// MuJoCo's messages go to [`mujoco_message`] instead of MuJoCo's default
/// handler, which prints them and appends them to a `MUJOCO_LOG.TXT` in the
/// current folder.
static LOG_HANDLER: Once = Once::new();

/// The only warning dropped: Gymnasium's `half_cheetah.xml` uses the
/// deprecated `settotalmass` attribute, and MuJoCo warns on every load.
const KNOWN_BENIGN_WARNING: &str = "'settotalmass' is deprecated";

/// Prints MuJoCo's warnings and errors to stderr (no log file), except the
/// known deprecation warning of Gymnasium's HalfCheetah model; information
/// and debug messages are dropped. MuJoCo ends the process after an error.
fn mujoco_message(message: &MjLogMessage) {
    let subject = message.subject();
    match message.level() {
        MjtLogLevel::mjLOG_WARNING if subject.contains(KNOWN_BENIGN_WARNING) => {}
        MjtLogLevel::mjLOG_WARNING => eprintln!("MuJoCo warning: {subject}"),
        MjtLogLevel::mjLOG_ERROR => eprintln!("MuJoCo error: {subject}"),
        _ => {}
    }
}

fn configure_mujoco_logging() {
    LOG_HANDLER.call_once(|| {
        // SAFETY: the handler must not be installed while another thread
        // uses MuJoCo. It is installed once, before the first model of this
        // crate is loaded, so no simulation of this crate exists yet, and
        // every loader of this crate waits on the `Once`. Code that drives
        // MuJoCo directly on another thread at the same moment is the only
        // case left, and is documented on `Simulation::from_path`. The
        // handler is thread-safe and never logs through MuJoCo.
        #[allow(unsafe_code)]
        unsafe {
            set_log_handler(mujoco_message);
        }
    });
}

/// A loaded MuJoCo model with its simulation data.
///
/// It mirrors the parts of Gymnasium's `MujocoEnv` that the `-v5`
/// environments use: [`Simulation::set_state`] (write `qpos`, `qvel`, then
/// `mj_forward`), [`Simulation::step`] (write `ctrl`, then `frame_skip` calls
/// of `mj_step`) and [`Simulation::reset`] (`mj_resetData`).
#[derive(Debug)]
pub struct Simulation {
    data: MjData<Arc<MjModel>>,
    name: String,
    frame_skip: usize,
    dt: f64,
    init_qpos: Vec<f64>,
    init_qvel: Vec<f64>,
}

impl Simulation {
    /// Loads `file_name` (for example `"hopper.xml"`) from the folder of
    /// Gymnasium's model files (see [`crate::assets`]).
    ///
    /// # Errors
    /// [`Error::AssetNotFound`] if the file is missing (run
    /// `scripts/setup-mujoco.sh`), [`Error::ModelLoad`] if MuJoCo rejects it,
    /// [`Error::InvalidConfig`] if `frame_skip` is 0.
    pub fn load(file_name: &str, frame_skip: usize) -> Result<Self> {
        let path = assets::model_path(file_name)?;
        Self::from_path(&path, frame_skip)
    }

    /// Loads the model file at `path`.
    ///
    /// The first load in a process installs a MuJoCo message handler that
    /// prints warnings and errors to stderr without writing MuJoCo's log
    /// file, and drops the deprecation warning that Gymnasium's
    /// `half_cheetah.xml` causes on every load. That global setting must not
    /// be changed while another thread uses MuJoCo directly, outside this
    /// crate; a program may install its own handler afterwards.
    ///
    /// # Errors
    /// As [`Simulation::load`].
    pub fn from_path(path: &Path, frame_skip: usize) -> Result<Self> {
        if frame_skip == 0 {
            return Err(Error::InvalidConfig {
                field: "frame_skip",
                reason: "must be at least 1".into(),
            });
        }
        if !path.is_file() {
            return Err(Error::AssetNotFound {
                path: path.to_path_buf(),
                source_of_dir: "the path given".into(),
            });
        }
        configure_mujoco_logging();
        let model = MjModel::from_xml(path).map_err(|e| Error::ModelLoad {
            path: path.to_path_buf(),
            reason: format!("{e:?}"),
        })?;
        let model = Arc::new(model);
        let data = MjData::try_new(model).map_err(|e| Error::ModelLoad {
            path: path.to_path_buf(),
            reason: format!("allocating the simulation data failed: {e:?}"),
        })?;
        let dt = data.model().opt().timestep * frame_skip as f64;
        let init_qpos = data.qpos().to_vec();
        let init_qvel = data.qvel().to_vec();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        Ok(Self {
            data,
            name,
            frame_skip,
            dt,
            init_qpos,
            init_qvel,
        })
    }

    /// The model file's name, for messages.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The MuJoCo model.
    pub fn model(&self) -> &MjModel {
        self.data.model()
    }

    /// The MuJoCo data, for reading anything this type does not expose.
    pub fn data(&self) -> &MjData<Arc<MjModel>> {
        &self.data
    }

    /// The MuJoCo data, mutably (for example for a raw `mj_step` loop).
    pub fn data_mut(&mut self) -> &mut MjData<Arc<MjModel>> {
        &mut self.data
    }

    /// Number of position coordinates (`nq`).
    pub fn nq(&self) -> usize {
        self.init_qpos.len()
    }

    /// Number of velocity coordinates (`nv`).
    pub fn nv(&self) -> usize {
        self.init_qvel.len()
    }

    /// Number of controls (`nu`).
    pub fn nu(&self) -> usize {
        self.data.ctrl().len()
    }

    /// Physics steps per [`Simulation::step`].
    pub fn frame_skip(&self) -> usize {
        self.frame_skip
    }

    /// Seconds per [`Simulation::step`]: the model's timestep times
    /// `frame_skip` (Gymnasium's `dt`).
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The positions right after loading (the model's `qpos0`), Gymnasium's
    /// `init_qpos`.
    pub fn init_qpos(&self) -> &[f64] {
        &self.init_qpos
    }

    /// The velocities right after loading (zeros), Gymnasium's `init_qvel`.
    pub fn init_qvel(&self) -> &[f64] {
        &self.init_qvel
    }

    /// Current positions, `nq` numbers.
    pub fn qpos(&self) -> &[f64] {
        self.data.qpos()
    }

    /// Current velocities, `nv` numbers.
    pub fn qvel(&self) -> &[f64] {
        self.data.qvel()
    }

    /// The controls last written by [`Simulation::step`], `nu` numbers
    /// (as given: MuJoCo clamps them to the control ranges when it uses
    /// them).
    pub fn ctrl(&self) -> &[f64] {
        self.data.ctrl()
    }

    /// The control ranges of the actuators, `nu` pairs `[low, high]`.
    pub fn ctrl_range(&self) -> &[[f64; 2]] {
        self.model().actuator_ctrlrange()
    }

    /// Number of bodies, the world body included.
    pub fn nbody(&self) -> usize {
        self.data.xpos().len()
    }

    /// The id of the body called `name`.
    ///
    /// # Errors
    /// [`Error::ModelMismatch`] if the model has no such body.
    pub fn body_id(&self, name: &str) -> Result<usize> {
        self.model()
            .name_to_id(MjtObjBase::mjOBJ_BODY, name)
            .ok_or_else(|| Error::ModelMismatch {
                model: self.name.clone(),
                reason: format!("no body named `{name}`"),
            })
    }

    /// Cartesian position of body `id`'s frame (`xpos`), as MuJoCo left it:
    /// after [`Simulation::step`] it is the position computed at the start
    /// of the last physics step, as Gymnasium reads it.
    ///
    /// # Panics
    /// If `id >= nbody`.
    pub fn body_xpos(&self, id: usize) -> [f64; 3] {
        self.data.xpos()[id]
    }

    /// External contact forces on each body in its centre-of-mass frame
    /// (`cfrc_ext`, `nbody` rows of 6: torque then force). Only up to date
    /// after [`Simulation::step_with_contact_forces`] (zeros after
    /// [`Simulation::reset`]).
    pub fn cfrc_ext(&self) -> &[[f64; 6]] {
        self.data.cfrc_ext()
    }

    /// `mj_resetData`: time, state, controls and warm starts back to the
    /// model's defaults.
    pub fn reset(&mut self) {
        self.data.reset();
    }

    /// Writes `qpos` and `qvel` and runs `mj_forward`, as Gymnasium's
    /// `MujocoEnv.set_state`.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] for wrong lengths, [`Error::NonFinite`] for
    /// NaN or infinite values; the state is unchanged then.
    pub fn set_state(&mut self, qpos: &[f64], qvel: &[f64]) -> Result<()> {
        check_vector("qpos", qpos, self.nq())?;
        check_vector("qvel", qvel, self.nv())?;
        self.data.qpos_mut().copy_from_slice(qpos);
        self.data.qvel_mut().copy_from_slice(qvel);
        self.data.forward();
        Ok(())
    }

    /// Writes `ctrl` and advances `frame_skip` physics steps (`mj_step`).
    /// MuJoCo clamps controls outside the actuators' ranges.
    ///
    /// # Errors
    /// [`Error::ShapeMismatch`] or [`Error::NonFinite`] for a malformed
    /// `ctrl`; nothing is stepped then.
    pub fn step(&mut self, ctrl: &[f64]) -> Result<()> {
        check_vector("ctrl", ctrl, self.nu())?;
        self.data.ctrl_mut().copy_from_slice(ctrl);
        for _ in 0..self.frame_skip {
            self.data.step();
        }
        Ok(())
    }

    /// [`Simulation::step`], then `mj_rnePostConstraint` as Gymnasium's
    /// `MujocoEnv` does after every step, so that [`Simulation::cfrc_ext`]
    /// is up to date. Only environments that read contact forces need it.
    ///
    /// # Errors
    /// As [`Simulation::step`].
    pub fn step_with_contact_forces(&mut self, ctrl: &[f64]) -> Result<()> {
        self.step(ctrl)?;
        self.data.rne_post_constraint();
        Ok(())
    }
}

fn check_vector(what: &'static str, x: &[f64], expected: usize) -> Result<()> {
    if x.len() != expected {
        return Err(Error::ShapeMismatch {
            what,
            expected,
            got: x.len(),
        });
    }
    if x.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite { what });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hopper() -> Simulation {
        Simulation::load("hopper.xml", 4).expect("run scripts/setup-mujoco.sh")
    }

    #[test]
    fn loads_hopper_with_gymnasium_dimensions() {
        let sim = hopper();
        assert_eq!((sim.nq(), sim.nv(), sim.nu(), sim.nbody()), (6, 6, 3, 5));
        assert!((sim.dt() - 0.008).abs() < 1e-15);
        assert_eq!(sim.init_qvel(), &[0.0; 6]);
        assert_eq!(sim.ctrl_range(), &[[-1.0, 1.0]; 3]);
        assert_eq!(sim.body_id("torso").unwrap(), 1);
        assert!(matches!(
            sim.body_id("nope"),
            Err(Error::ModelMismatch { .. })
        ));
    }

    #[test]
    fn set_state_then_step_is_deterministic() {
        let mut a = hopper();
        let mut b = hopper();
        let qpos = [0.01, 1.26, 0.02, -0.01, 0.0, 0.01];
        let qvel = [0.1, -0.2, 0.05, 0.0, 0.3, -0.1];
        for sim in [&mut a, &mut b] {
            sim.set_state(&qpos, &qvel).unwrap();
            assert_eq!(sim.qpos(), &qpos);
            for _ in 0..10 {
                sim.step(&[0.5, -0.3, 0.9]).unwrap();
            }
            assert_eq!(sim.ctrl(), &[0.5, -0.3, 0.9]);
        }
        assert_eq!(a.qpos(), b.qpos());
        assert_eq!(a.qvel(), b.qvel());
        assert_ne!(a.qpos(), &qpos);
        assert!((a.data().time() - 10.0 * a.dt()).abs() < 1e-12);
        a.reset();
        assert_eq!(a.qpos(), a.init_qpos());
        assert_eq!(a.data().time(), 0.0);
    }

    #[test]
    fn rejects_malformed_input() {
        let mut sim = hopper();
        assert!(matches!(
            sim.step(&[0.0; 2]),
            Err(Error::ShapeMismatch { what: "ctrl", .. })
        ));
        assert!(matches!(
            sim.step(&[0.0, f64::NAN, 0.0]),
            Err(Error::NonFinite { what: "ctrl" })
        ));
        assert!(matches!(
            sim.set_state(&[0.0; 6], &[0.0; 5]),
            Err(Error::ShapeMismatch { what: "qvel", .. })
        ));
        assert!(matches!(
            Simulation::load("hopper.xml", 0),
            Err(Error::InvalidConfig { .. })
        ));
        let missing = Simulation::from_path(Path::new("/nonexistent/model.xml"), 1);
        assert!(matches!(missing, Err(Error::AssetNotFound { .. })));
    }

    #[test]
    fn an_unstable_state_is_reset_by_mujoco_with_a_warning() {
        let mut sim = hopper();
        sim.set_state(&[0.0, 1.25, 0.0, 0.0, 0.0, 0.0], &[1e11; 6])
            .unwrap();
        sim.step(&[0.0; 3]).unwrap();
        // MuJoCo warns (printed to stderr by our handler) and resets the
        // data instead of ending the process.
        let warnings: i32 = sim.data().warning().iter().map(|w| w.number).sum();
        assert!(warnings > 0);
        assert!(sim.qvel().iter().all(|v| v.abs() < 1e10));
    }

    #[test]
    fn a_bad_model_file_is_an_error_not_a_crash() {
        let dir = std::env::temp_dir().join(format!("red-mujoco-bad-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bad.xml");
        std::fs::write(&path, "<mujoco><worldbody><body></mujoco>").unwrap();
        let err = Simulation::from_path(&path, 1).unwrap_err();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(matches!(err, Error::ModelLoad { .. }), "{err}");
    }
}
