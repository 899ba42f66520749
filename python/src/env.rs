//! `VecEnv`: the training environment of `cpmx train` (the spec's `training:` section in any
//! of its fidelities) as a batched environment for Python. It is `cpmx_env::VecEnv` itself:
//! with the same seed its episodes are `cpmx train`'s, bit for bit.

use std::path::PathBuf;
use std::sync::Mutex;

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::{PyIndexError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::CpmxError;

/// What changes as the environment steps.
struct Stepping {
    env: cpmx_env::VecEnv,
    result: cpmx_env::StepResult,
    /// The observations last handed out, `[E][A][O]` (for resets of some environments).
    last_observations: Vec<f32>,
    actions: Vec<f32>,
    /// Threads that step environments in parallel (`None`: rayon's global pool).
    pool: Option<rayon::ThreadPool>,
}

/// A batch of environments of the spec's training scenario. See `cpmx/_cpmx.pyi`.
#[pyclass(module = "cpmx._cpmx", name = "VecEnv")]
pub struct VecEnv {
    stepping: Mutex<Stepping>,
    config: cpmx_env::EnvConfig,
    paths: Vec<cpmx_world::ReferencePath>,
    fidelity: String,
    seed: u64,
}

impl VecEnv {
    fn lock(&self) -> PyResult<std::sync::MutexGuard<'_, Stepping>> {
        self.stepping
            .lock()
            .map_err(|_| CpmxError::new_err("the environment failed in an earlier call and cannot be used"))
    }

    fn dims(&self) -> (usize, usize, usize) {
        (
            self.config.scenario.envs,
            self.config.scenario.agents,
            self.config.observation.size(),
        )
    }
}

/// A new `cpmx_env::VecEnv` for `config` with the streams of `seed`.
fn make_env(
    config: &cpmx_env::EnvConfig,
    paths: &[cpmx_world::ReferencePath],
    seed: u64,
) -> PyResult<cpmx_env::VecEnv> {
    let mut env =
        cpmx_env::VecEnv::new(config.clone(), paths, seed).map_err(|e| CpmxError::new_err(e.to_string()))?;
    env.set_keep_final_observations(true);
    Ok(env)
}

/// A numpy array of shape `shape` that takes `values` over (no copy of the elements).
fn array<'py, T: numpy::Element>(
    py: Python<'py>,
    values: Vec<T>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, values).reshape(shape)?.into_any())
}

#[pymethods]
impl VecEnv {
    #[new]
    #[pyo3(signature = (spec, fidelity=None, num_envs=32, seed=0, data=None, threads=None))]
    fn new(
        py: Python<'_>,
        spec: PathBuf,
        fidelity: Option<String>,
        num_envs: usize,
        seed: u64,
        data: Option<&Bound<'_, PyAny>>,
        threads: Option<usize>,
    ) -> PyResult<Self> {
        if num_envs == 0 {
            return Err(PyValueError::new_err("`num_envs` must be at least 1"));
        }
        let data = crate::data_folders(data)?;
        let prepared = py.detach(|| -> PyResult<_> {
            let checked = crate::load(&spec, &data)?;
            let Some(training) = &checked.spec.training else {
                return Err(CpmxError::new_err(format!(
                    "`{}` has no `training:` section: the environment is the training scenario a \
                     spec's `training:` section declares (see docs/language.md)",
                    spec.display()
                )));
            };
            let fidelity = fidelity.unwrap_or_else(|| training.fidelity.names()[0].clone());
            let setup = cpmx_train::TrainingSetup::prepare(&checked, &fidelity)
                .map_err(|e| CpmxError::new_err(format!("{}: {e}", spec.display())))?;
            let mut config = setup.env;
            config.scenario.envs = num_envs;
            let env = make_env(&config, &setup.paths, seed)?;
            Ok((config, setup.paths, env, fidelity))
        })?;
        let (config, paths, env, fidelity) = prepared;
        let pool = match threads {
            None => None,
            Some(n) => Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n.max(1))
                    .build()
                    .map_err(|e| CpmxError::new_err(format!("cannot start {n} threads: {e}")))?,
            ),
        };
        let (e, a, o) = (num_envs, config.scenario.agents, config.observation.size());
        Ok(VecEnv {
            stepping: Mutex::new(Stepping {
                env,
                result: cpmx_env::StepResult::default(),
                last_observations: vec![0.0; e * a * o],
                actions: Vec::with_capacity(e * a * 2),
                pool,
            }),
            config,
            paths,
            fidelity,
            seed,
        })
    }

    /// Re-places environments: all of them (`mask=None`), or those whose `mask` entry is true;
    /// `seed` restarts every random stream from that seed first. Returns the observations.
    #[pyo3(signature = (seed=None, mask=None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seed: Option<u64>,
        mask: Option<Vec<bool>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (e, a, o) = self.dims();
        if seed.is_some() && mask.is_some() {
            return Err(PyValueError::new_err(
                "give `seed` (restart every environment's streams) or `mask` (reset some), not both",
            ));
        }
        if let Some(mask) = &mask
            && mask.len() != e
        {
            return Err(PyValueError::new_err(format!(
                "`mask` has {} entries for {e} environments",
                mask.len()
            )));
        }
        if let Some(seed) = seed {
            // As `cpmx train` starts a seed: new streams, then a reset of every environment.
            let env = py.detach(|| make_env(&self.config, &self.paths, seed))?;
            self.lock()?.env = env;
            self.seed = seed;
        }
        let mut guard = self.lock()?;
        let s = &mut *guard;
        py.detach(|| match &mask {
            Some(mask) => s.env.reset_masked(mask, &mut s.last_observations),
            None => s.last_observations = s.env.reset_all(),
        });
        array(py, s.last_observations.clone(), &[e, a, o])
    }

    /// One step of every environment: `actions[E, A, 2]` (speed m/s, steering rad) →
    /// `(observations, reward, terminated, truncated, info)`.
    fn step<'py>(
        &self,
        py: Python<'py>,
        actions: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, pyo3::types::PyTuple>> {
        let (e, a, o) = self.dims();
        let np = py.import("numpy")?;
        let contiguous = np.call_method1("ascontiguousarray", (actions, np.getattr("float32")?))?;
        let actions: PyReadonlyArray3<'py, f32> = contiguous
            .extract()
            .map_err(|_| PyValueError::new_err(format!("`actions` must have 3 dimensions [{e}, {a}, 2]")))?;
        if actions.shape() != [e, a, 2] {
            return Err(PyValueError::new_err(format!(
                "`actions` has shape {:?}; expected [{e}, {a}, 2] (environments, agents, speed and steering)",
                actions.shape()
            )));
        }
        let mut guard = self.lock()?;
        let s = &mut *guard;
        s.actions.clear();
        s.actions.extend_from_slice(actions.as_slice()?);
        if let Some(bad) = s.actions.iter().find(|v| !v.is_finite()) {
            return Err(PyValueError::new_err(format!("`actions` holds {bad}")));
        }
        py.detach(|| {
            let Stepping {
                env,
                result,
                actions,
                pool,
                ..
            } = &mut *s;
            match pool {
                Some(pool) => pool.install(|| env.step_into(actions, result)),
                None => env.step_into(actions, result),
            }
        });
        if let Some(failure) = s.env.failure() {
            return Err(CpmxError::new_err(format!("a vehicle stack failed: {failure}")));
        }
        let r = &mut s.result;
        s.last_observations.copy_from_slice(&r.observations);
        let observations = array(py, std::mem::take(&mut r.observations), &[e, a, o])?;
        let reward = array(py, r.rewards.clone(), &[e, a])?;
        let terminated: Vec<bool> = (0..e * a).map(|i| r.done[i / a] && !r.truncated[i / a]).collect();
        let terminated = array(py, terminated, &[e, a])?;
        let truncated = array(py, r.truncated.clone(), &[e])?;
        let info = PyDict::new(py);
        if r.done.iter().any(|&d| d) {
            info.set_item(
                "final_obs",
                array(py, std::mem::take(&mut r.final_observations), &[e, a, o])?,
            )?;
            info.set_item("_final_obs", array(py, r.done.clone(), &[e])?)?;
        }
        info.set_item("episode_return", array(py, r.episode_reward.clone(), &[e, a])?)?;
        let flag = |f: fn(&cpmx_env::AgentStepInfo) -> bool| r.agents.iter().map(f).collect::<Vec<bool>>();
        info.set_item(
            "collides_with_agents",
            array(py, flag(|i| i.collides_with_agents), &[e, a])?,
        )?;
        info.set_item(
            "collides_with_boundary",
            array(py, flag(|i| i.collides_with_boundary), &[e, a])?,
        )?;
        info.set_item("agent_replaced", array(py, flag(|i| i.reset), &[e, a])?)?;
        let stopped: Vec<u32> = r.agents.iter().map(|i| i.follower_stopped_periods).collect();
        info.set_item("follower_stopped_periods", array(py, stopped, &[e, a])?)?;
        pyo3::types::PyTuple::new(py, [observations, reward, terminated, truncated, info.into_any()])
    }

    /// The centralised critic's input: every agent's observation of each environment,
    /// concatenated, `[E, A × O]`.
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let (e, a, o) = self.dims();
        let s = self.lock()?;
        array(py, s.last_observations.clone(), &[e, a * o])
    }

    /// Environment `env` drawn as an RGB image `uint8[H, W, 3]`, `width` pixels wide.
    #[pyo3(signature = (env=0, width=640))]
    fn render<'py>(&self, py: Python<'py>, env: usize, width: usize) -> PyResult<Bound<'py, PyAny>> {
        let s = self.lock()?;
        let image = s.env.render_rgb(env, width).ok_or_else(|| {
            PyIndexError::new_err(format!("no environment {env} of {}", self.config.scenario.envs))
        })?;
        array(py, image.pixels, &[image.height, image.width, 3])
    }

    /// `["agent_0", "agent_1", ...]`.
    #[getter]
    fn agents(&self) -> Vec<String> {
        (0..self.config.scenario.agents)
            .map(|i| format!("agent_{i}"))
            .collect()
    }

    #[getter]
    fn num_envs(&self) -> usize {
        self.config.scenario.envs
    }

    #[getter]
    fn num_agents(&self) -> usize {
        self.config.scenario.agents
    }

    #[getter]
    fn observation_size(&self) -> usize {
        self.config.observation.size()
    }

    #[getter]
    fn state_size(&self) -> usize {
        self.config.scenario.agents * self.config.observation.size()
    }

    /// The lowest action: `[-max speed m/s, -max steering rad]`, float32.
    #[getter]
    fn action_low<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = self.config.vehicle;
        array(
            py,
            vec![-(v.max_speed_mps as f32), -(v.max_steering_rad as f32)],
            &[2],
        )
    }

    /// The highest action: `[max speed m/s, max steering rad]`, float32.
    #[getter]
    fn action_high<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = self.config.vehicle;
        array(py, vec![v.max_speed_mps as f32, v.max_steering_rad as f32], &[2])
    }

    /// Steps per episode (the time limit).
    #[getter]
    fn episode_steps(&self) -> u32 {
        self.config.scenario.episode_steps
    }

    /// The policy step [s].
    #[getter]
    fn dt(&self) -> f64 {
        self.config.dt_s
    }

    #[getter]
    fn fidelity(&self) -> String {
        self.fidelity.clone()
    }

    /// The seed the environments' streams were last started from.
    #[getter]
    fn seed(&self) -> u64 {
        self.seed
    }

    /// Gymnasium's autoreset mode: `"same-step"` (`AutoresetMode.SAME_STEP`).
    #[getter]
    fn autoreset_mode(&self) -> &'static str {
        "same-step"
    }

    fn __repr__(&self) -> String {
        let (e, a, o) = self.dims();
        format!(
            "VecEnv(fidelity={:?}, num_envs={e}, agents={a}, observation_size={o}, seed={})",
            self.fidelity, self.seed
        )
    }
}

/// The learner's environment as `cpmx train` makes it for `seed` (cpmx_train's
/// `TrainingEnv` on the section's own number of environments, reset as the learner resets it),
/// stepped with `actions[T, E, A, 2]`: the observations `[T + 1, E, A, O]` (the reset's first)
/// and rewards `[T, E, A]`. For tests that compare `VecEnv` with it.
#[pyfunction]
#[pyo3(signature = (spec, fidelity, seed, actions, data=None))]
pub fn _training_rollout<'py>(
    py: Python<'py>,
    spec: PathBuf,
    fidelity: String,
    seed: u64,
    actions: numpy::PyReadonlyArray4<'py, f32>,
    data: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    use cpmx_learn::Environment;
    let data = crate::data_folders(data)?;
    let shape = actions.shape().to_vec();
    let actions = actions.as_slice()?.to_vec();
    let (observations, rewards, dims) = py.detach(|| -> PyResult<_> {
        let checked = crate::load(&spec, &data)?;
        let setup = cpmx_train::TrainingSetup::prepare(&checked, &fidelity)
            .map_err(|e| CpmxError::new_err(e.to_string()))?;
        let mut env = cpmx_train::TrainingEnv::new(setup.env.clone(), &setup.paths, seed)
            .map_err(|e| CpmxError::new_err(e.to_string()))?;
        let (e, a, o) = (env.num_envs(), env.num_agents(), env.obs_dim());
        if shape[1..] != [e, a, 2] {
            return Err(PyValueError::new_err(format!(
                "`actions` has shape {shape:?}; expected [T, {e}, {a}, 2]"
            )));
        }
        let mut observations = env.reset_all();
        let mut rewards = Vec::new();
        for step in actions.chunks_exact(e * a * 2) {
            let result = env.step(step).map_err(CpmxError::new_err)?;
            observations.extend_from_slice(&result.observations);
            rewards.extend_from_slice(&result.rewards);
        }
        Ok((observations, rewards, (e, a, o)))
    })?;
    let (e, a, o) = dims;
    let steps = shape[0];
    Ok((
        array(py, observations, &[steps + 1, e, a, o])?,
        array(py, rewards, &[steps, e, a])?,
    ))
}
