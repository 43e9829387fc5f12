//! The driving scenario (red-drive) for Python: the environment without its
//! time limit (the Gymnasium registration adds Gymnasium's `TimeLimit`),
//! a reference rollout through the Rust `make_env` for tests, the scripted
//! expert, and rendering to an RGB array.

use std::io::BufReader;

use ndarray::Array3;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use red_core::{Env, Info};
use red_drive::render::{PathEnd, PathSpec, RenderOptions, render_png};
use red_drive::{ACT_DIM, CarState, DriveConfig, DriveEnv, Expert, NUM_RAYS, OBS_DIM};

use crate::arrays::{core_err, drive_err, matrix};

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDriveEnv>()?;
    m.add_function(wrap_pyfunction!(drive_rollout, m)?)?;
    m.add_function(wrap_pyfunction!(drive_expert_demos_json, m)?)?;
    m.add_function(wrap_pyfunction!(drive_default_config_json, m)?)?;
    m.add_function(wrap_pyfunction!(drive_road_of_json, m)?)?;
    m.add("DRIVE_OBS_DIM", OBS_DIM)?;
    m.add("DRIVE_ACT_DIM", ACT_DIM)?;
    m.add("DRIVE_ENV_ID", red_drive::ENV_ID)?;
    Ok(())
}

/// A `DriveConfig` from JSON text (missing fields take their defaults),
/// validated.
fn config_from(text: Option<&str>) -> PyResult<DriveConfig> {
    let c: DriveConfig = match text {
        None => DriveConfig::default(),
        Some(t) => serde_json::from_str(t)
            .map_err(|e| PyValueError::new_err(format!("drive config: {e}")))?,
    };
    c.validate().map_err(drive_err)?;
    Ok(c)
}

fn info_dict<'py>(py: Python<'py>, info: &Info) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in info.iter() {
        d.set_item(k, v)?;
    }
    Ok(d)
}

/// The default road as JSON text.
#[pyfunction]
fn drive_default_config_json() -> PyResult<String> {
    serde_json::to_string(&DriveConfig::default()).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// The road a drive demo (JSON text) was made on (`scenario::road_of`), as
/// JSON text; files without one were made on the default road.
#[pyfunction]
fn drive_road_of_json(text: &str) -> PyResult<String> {
    let demos = red_core::Demos::from_json_str(text).map_err(core_err)?;
    let (road, _) = red_drive::scenario::road_of(&demos).map_err(drive_err)?;
    serde_json::to_string(&road).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// `red_drive::expert_demos`: `episodes` runs of the scripted expert, as
/// demo JSON text.
#[pyfunction]
#[pyo3(signature = (config_json = None, episodes = 1, seed = 0))]
fn drive_expert_demos_json(
    py: Python<'_>,
    config_json: Option<&str>,
    episodes: usize,
    seed: u64,
) -> PyResult<String> {
    let config = config_from(config_json)?;
    let demos = py
        .detach(|| red_drive::expert_demos(&config, episodes, seed))
        .map_err(drive_err)?;
    serde_json::to_string(&demos).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// The reference: `red_drive::make_env` (the Rust env with its own time
/// limit), reset with `seed`, then the rows of `actions` (n, 2) until the
/// episode ends. Returns observations (k+1, 24), rewards (k,), and the
/// `terminated` and `truncated` flags of the last step.
#[pyfunction]
#[pyo3(signature = (actions, seed, config_json = None))]
#[allow(clippy::type_complexity)]
fn drive_rollout<'py>(
    py: Python<'py>,
    actions: &Bound<'py, PyAny>,
    seed: u64,
    config_json: Option<&str>,
) -> PyResult<(
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<f64>>,
    bool,
    bool,
)> {
    let config = config_from(config_json)?;
    let acts = matrix(actions, "actions", Some(ACT_DIM))?;
    let (obs, rewards, term, trunc) = py
        .detach(|| -> red_drive::Result<_> {
            let mut env = red_drive::make_env(&config)?;
            let (o, _) = env.reset(Some(seed))?;
            let mut obs = o;
            let mut rewards = Vec::new();
            let (mut term, mut trunc) = (false, false);
            for a in acts.rows() {
                let step = env.step(&a.to_vec())?;
                obs.extend_from_slice(&step.observation);
                rewards.push(step.reward);
                term = step.terminated;
                trunc = step.truncated;
                if term || trunc {
                    break;
                }
            }
            Ok((obs, rewards, term, trunc))
        })
        .map_err(drive_err)?;
    let n = obs.len() / OBS_DIM;
    let obs = ndarray::Array2::from_shape_vec((n, OBS_DIM), obs)
        .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    Ok((
        obs.into_pyarray(py),
        ndarray::Array1::from(rewards).into_pyarray(py),
        term,
        trunc,
    ))
}

/// What `DriveCore.step` returns: observation, reward, terminated, info.
type StepOut<'py> = (Bound<'py, PyArray1<f64>>, f64, bool, Bound<'py, PyDict>);

/// The driving scenario without a time limit: `reset`, `step` (reward =
/// metres gained along the road; `terminated` on a collision or at the end
/// of the road), the scripted expert's action, and rendering.
#[pyclass(name = "DriveCore", module = "red._red")]
pub(crate) struct PyDriveEnv {
    env: DriveEnv,
    /// The car's states this episode, for rendering its path.
    poses: Vec<CarState>,
    /// How the episode ended, for rendering.
    end: PathEnd,
}

#[pymethods]
impl PyDriveEnv {
    /// The scenario of `config_json` (a `DriveConfig` as JSON; missing
    /// fields take their defaults).
    #[new]
    #[pyo3(signature = (config_json = None))]
    fn new(config_json: Option<&str>) -> PyResult<Self> {
        let config = config_from(config_json)?;
        let env = DriveEnv::new(&config).map_err(drive_err)?;
        Ok(Self {
            env,
            poses: Vec::new(),
            end: PathEnd::Stopped,
        })
    }

    /// Starts an episode; with a seed the start noise restarts from it.
    /// Returns the observation (24,) float64 and the info dict.
    #[pyo3(signature = (seed = None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seed: Option<u64>,
    ) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyDict>)> {
        let (obs, info) = self.env.reset(seed).map_err(core_err)?;
        self.poses = vec![*self.env.car()];
        self.end = PathEnd::Stopped;
        Ok((obs.into_pyarray(py), info_dict(py, &info)?))
    }

    /// Starts an episode from the state whose first observation is `obs`
    /// (`CarState::from_first_observation`: at the start of the road), for
    /// replaying a demonstration's actions.
    fn reset_to_observation<'py>(
        &mut self,
        py: Python<'py>,
        obs: Vec<f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let car = CarState::from_first_observation(self.env.config(), &obs).map_err(drive_err)?;
        let o = self.env.reset_to(car).map_err(drive_err)?;
        self.poses = vec![*self.env.car()];
        self.end = PathEnd::Stopped;
        Ok(o.into_pyarray(py))
    }

    /// One control step with `action` = [steering, accelerator/brake] (out
    /// of [-1, 1] is clipped). Returns (observation, reward, terminated,
    /// info).
    fn step<'py>(&mut self, py: Python<'py>, action: Vec<f64>) -> PyResult<StepOut<'py>> {
        let step = self.env.step(&action).map_err(core_err)?;
        self.poses.push(*self.env.car());
        if step.terminated {
            self.end = if step.info.get(red_drive::env::INFO_SUCCESS) == Some(1.0) {
                PathEnd::Success
            } else {
                PathEnd::Collision
            };
        }
        Ok((
            step.observation.into_pyarray(py),
            step.reward,
            step.terminated,
            info_dict(py, &step.info)?,
        ))
    }

    /// The scripted expert's action in the current state (it sees the true
    /// layout).
    fn expert_action(&self) -> Vec<f64> {
        Expert::new(self.env.world()).act(self.env.car()).to_vec()
    }

    /// Bounds of the observation space: (low, high), each (24,).
    fn observation_bounds(&self) -> (Vec<f64>, Vec<f64>) {
        match self.env.observation_space() {
            red_core::Space::Box(b) => (b.low.clone(), b.high.clone()),
            other => (vec![0.0; other.dim()], vec![0.0; other.dim()]),
        }
    }

    /// The settings as JSON text.
    fn config_json(&self) -> PyResult<String> {
        serde_json::to_string(self.env.config()).map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// The car's state: (x, y, heading, speed).
    fn car(&self) -> (f64, f64, f64, f64) {
        let c = self.env.car();
        (c.x, c.y, c.heading, c.speed)
    }

    /// The whole road with the episode's path so far and the current lidar
    /// rays, as an RGB array (height, width, 3) uint8 (red-drive's PNG
    /// rendering, `width` pixels wide).
    #[pyo3(signature = (width = 1600))]
    fn render_rgb<'py>(&self, py: Python<'py>, width: u32) -> PyResult<Bound<'py, PyArray3<u8>>> {
        let config = self.env.config().clone();
        let path = PathSpec {
            label: "car".into(),
            colour: [30, 90, 200],
            poses: self.poses.clone(),
            end: self.end,
            lidar: vec![(*self.env.car(), *self.env.lidar_ranges())],
        };
        let options = RenderOptions {
            width_px: width,
            legend: false,
            ..RenderOptions::default()
        };
        let img = py.detach(|| render_rgb(&config, &path, &options))?;
        Ok(img.into_pyarray(py))
    }

    /// Number of lidar rays.
    #[classattr]
    fn num_rays() -> usize {
        NUM_RAYS
    }
}

/// Draws through `render_png` into a temporary file and decodes it.
fn render_rgb(
    config: &DriveConfig,
    path: &PathSpec,
    options: &RenderOptions,
) -> PyResult<Array3<u8>> {
    let dir = tempfile::tempdir().map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    let file = dir.path().join("frame.png");
    render_png(&file, config, std::slice::from_ref(path), options).map_err(drive_err)?;
    let f = std::fs::File::open(&file).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    let mut decoder = png::Decoder::new(BufReader::new(f));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder
        .read_info()
        .map_err(|e| PyRuntimeError::new_err(format!("decoding the frame: {e}")))?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let frame = reader
        .next_frame(&mut buf)
        .map_err(|e| PyRuntimeError::new_err(format!("decoding the frame: {e}")))?;
    let (w, h) = (frame.width as usize, frame.height as usize);
    let channels = frame.color_type.samples();
    let bytes = &buf[..frame.buffer_size()];
    let img = Array3::from_shape_fn((h, w, 3), |(y, x, c)| {
        let px = (y * w + x) * channels;
        if channels >= 3 {
            bytes[px + c]
        } else {
            bytes[px]
        }
    });
    Ok(img)
}
