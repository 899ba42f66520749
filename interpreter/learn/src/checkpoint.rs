//! The files a training run writes: actor/critic weights in the inference actor's layout, and
//! the checkpoint (everything needed to continue to the same weights as an uninterrupted run)
//! as one safetensors file.
//!
//! Checkpoint contents: tensors `actor.*`, `critic.*`, `best_actor.*`, `best_critic.*` (F32, the
//! networks' own layout), `adam.actor.m`, `adam.actor.v`, `adam.critic.m`, `adam.critic.v`
//! (flat F32), `state.observations` (`[E][N][D]`), `state.episode_return` (`[E][N]`),
//! `env.state` (U8, the environment's own bytes); metadata (as sorted `key=value` lines of
//! the one header entry `cpmx-learn`, so that equal runs give equal bytes) `format`, `seed`, `iteration`,
//! `adam_steps`, `best_reward` (bits of the f64, hex), `hyperparameters` (must match to resume),
//! and the word position of each random stream (`rng.train/actions`, ...).

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap};

use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;
use safetensors::{Dtype, SafeTensors, View};

use crate::env::Environment;
use crate::mlp::Mlp;
use crate::optim::AdamState;
use crate::trainer::{Hyperparameters, STREAMS, TrainError, Trainer, stream_key};

/// The checkpoint format tag.
const FORMAT: &str = "cpmx-learn/checkpoint/v1";

/// A tensor to serialise.
struct Owned {
    dtype: Dtype,
    shape: Vec<usize>,
    bytes: Vec<u8>,
}

impl View for Owned {
    fn dtype(&self) -> Dtype {
        self.dtype
    }
    fn shape(&self) -> &[usize] {
        &self.shape
    }
    fn data(&self) -> Cow<'_, [u8]> {
        Cow::Borrowed(&self.bytes)
    }
    fn data_len(&self) -> usize {
        self.bytes.len()
    }
}

fn f32_tensor(shape: Vec<usize>, values: &[f32]) -> Owned {
    Owned {
        dtype: Dtype::F32,
        shape,
        bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
    }
}

fn network_tensors(mlp: &Mlp, prefix: &str, out: &mut Vec<(String, Owned)>) {
    for (name, shape, values) in mlp.named_tensors(prefix) {
        out.push((name, f32_tensor(shape, values)));
    }
}

fn serialize(tensors: Vec<(String, Owned)>, metadata: Option<HashMap<String, String>>) -> Vec<u8> {
    safetensors::serialize(tensors, metadata).expect("tensor sizes match their shapes")
}

/// The safetensors header key that holds the checkpoint's metadata. safetensors writes a
/// header's metadata map in hash order, so the entries go into this one value as sorted
/// `key=value` lines: the same run gives the same bytes.
const METADATA_KEY: &str = "cpmx-learn";

fn pack_metadata(entries: BTreeMap<String, String>) -> HashMap<String, String> {
    let lines: Vec<String> = entries.into_iter().map(|(k, v)| format!("{k}={v}")).collect();
    HashMap::from([(METADATA_KEY.to_owned(), lines.join("\n"))])
}

fn unpack_metadata(metadata: &HashMap<String, String>) -> BTreeMap<String, String> {
    metadata
        .get(METADATA_KEY)
        .map(|text| {
            text.lines()
                .filter_map(|line| line.split_once('='))
                .map(|(k, v)| (k.to_owned(), v.to_owned()))
                .collect()
        })
        .unwrap_or_default()
}

/// A network as a safetensors file with tensors `{prefix}.{l}.weight|bias` (F32): the layout
/// `mlp: {weights: ...}` reads (`prefix = "actor"`).
pub fn network_file(mlp: &Mlp, prefix: &str) -> Vec<u8> {
    let mut tensors = Vec::new();
    network_tensors(mlp, prefix, &mut tensors);
    serialize(tensors, None)
}

fn read_f32(tensors: &SafeTensors<'_>, name: &str, len: usize) -> Result<Vec<f32>, TrainError> {
    let view = tensors
        .tensor(name)
        .map_err(|_| TrainError::Checkpoint(format!("tensor `{name}` is missing")))?;
    if view.dtype() != Dtype::F32 || view.data().len() != 4 * len {
        return Err(TrainError::Checkpoint(format!(
            "tensor `{name}` is not {len} float32 values"
        )));
    }
    Ok(view
        .data()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect())
}

fn read_network(bytes: &[u8], prefix: &str, sizes: &[usize]) -> Result<Mlp, TrainError> {
    let mlp = Mlp::from_safetensors(bytes, prefix).map_err(|e| TrainError::Checkpoint(e.to_string()))?;
    if mlp.sizes() != sizes {
        return Err(TrainError::Checkpoint(format!(
            "`{prefix}` has layers {:?}, the hyperparameters say {sizes:?}",
            mlp.sizes()
        )));
    }
    Ok(mlp)
}

impl<E: Environment> Trainer<E> {
    /// The current actor as a weights file (`actor.{l}.*`).
    pub fn actor_file(&self) -> Vec<u8> {
        network_file(&self.actor, "actor")
    }

    /// The best actor (SigmaRL's rule) as a weights file (`actor.{l}.*`).
    pub fn best_actor_file(&self) -> Vec<u8> {
        network_file(&self.best_actor, "actor")
    }

    /// The current critic as a weights file (`critic.{l}.*`).
    pub fn critic_file(&self) -> Vec<u8> {
        network_file(&self.critic, "critic")
    }

    /// The checkpoint after the completed iterations (see the module documentation).
    pub fn checkpoint(&self) -> Vec<u8> {
        let mut tensors = Vec::new();
        network_tensors(&self.actor, "actor", &mut tensors);
        network_tensors(&self.critic, "critic", &mut tensors);
        network_tensors(&self.best_actor, "best_actor", &mut tensors);
        network_tensors(&self.best_critic, "best_critic", &mut tensors);
        for (name, values) in [
            ("adam.actor.m", &self.adam_actor.m),
            ("adam.actor.v", &self.adam_actor.v),
            ("adam.critic.m", &self.adam_critic.m),
            ("adam.critic.v", &self.adam_critic.v),
            ("state.observations", &self.observations),
            ("state.episode_return", &self.episode_return),
        ] {
            tensors.push((name.to_owned(), f32_tensor(vec![values.len()], values)));
        }
        let env = self.env.save_state();
        tensors.push((
            "env.state".to_owned(),
            Owned {
                dtype: Dtype::U8,
                shape: vec![env.len()],
                bytes: env,
            },
        ));
        let mut meta = BTreeMap::from([
            ("format".to_owned(), FORMAT.to_owned()),
            ("seed".to_owned(), self.seed.to_string()),
            ("iteration".to_owned(), self.iteration.to_string()),
            ("adam_steps".to_owned(), self.adam_steps.to_string()),
            (
                "best_reward".to_owned(),
                format!("{:016x}", self.best_reward.to_bits()),
            ),
            ("hyperparameters".to_owned(), self.hp.fingerprint()),
        ]);
        for (name, rng) in
            STREAMS[1..]
                .iter()
                .zip([&self.rng_actions, &self.rng_minibatches, &self.rng_entropy])
        {
            meta.insert(format!("rng.{name}"), rng.get_word_pos().to_string());
        }
        serialize(tensors, Some(pack_metadata(meta)))
    }

    /// Continue a run from [`Trainer::checkpoint`] bytes with the same hyperparameters; `env`
    /// is restored from the checkpoint's `env.state`.
    pub fn resume(mut env: E, hp: Hyperparameters, bytes: &[u8]) -> Result<Self, TrainError> {
        let bad = |what: String| TrainError::Checkpoint(what);
        let (envs, agents, obs_dim) = (env.num_envs(), env.num_agents(), env.obs_dim());
        hp.check(envs, agents, obs_dim)?;
        let tensors =
            SafeTensors::deserialize(bytes).map_err(|e| bad(format!("not a checkpoint file: {e}")))?;
        let (_, header) = SafeTensors::read_metadata(bytes).map_err(|e| bad(e.to_string()))?;
        let meta = unpack_metadata(&header.metadata().clone().unwrap_or_default());
        let get = |key: &str| {
            meta.get(key)
                .cloned()
                .ok_or_else(|| bad(format!("metadata `{key}` is missing")))
        };
        let number = |key: &str| -> Result<u128, TrainError> {
            get(key)?
                .parse()
                .map_err(|_| bad(format!("metadata `{key}` is not a number")))
        };
        if get("format")? != FORMAT {
            return Err(bad(format!("format is not {FORMAT}")));
        }
        if get("hyperparameters")? != hp.fingerprint() {
            return Err(bad("it was made with different hyperparameters".into()));
        }
        let seed = number("seed")? as u64;
        let actor_sizes = crate::trainer::layer_sizes(obs_dim, &hp.actor_hidden, 4);
        let critic_sizes = crate::trainer::layer_sizes(agents * obs_dim, &hp.critic_hidden, 1);
        let actor = read_network(bytes, "actor", &actor_sizes)?;
        let critic = read_network(bytes, "critic", &critic_sizes)?;
        let best_actor = read_network(bytes, "best_actor", &actor_sizes)?;
        let best_critic = read_network(bytes, "best_critic", &critic_sizes)?;
        let (na, nc) = (actor.params.len(), critic.params.len());
        let adam_actor = AdamState {
            m: read_f32(&tensors, "adam.actor.m", na)?,
            v: read_f32(&tensors, "adam.actor.v", na)?,
        };
        let adam_critic = AdamState {
            m: read_f32(&tensors, "adam.critic.m", nc)?,
            v: read_f32(&tensors, "adam.critic.v", nc)?,
        };
        let observations = read_f32(&tensors, "state.observations", envs * agents * obs_dim)?;
        let episode_return = read_f32(&tensors, "state.episode_return", envs * agents)?;
        let env_state = tensors
            .tensor("env.state")
            .map_err(|_| bad("tensor `env.state` is missing".into()))?;
        env.load_state(env_state.data())
            .map_err(TrainError::Environment)?;
        let stream = |i: usize| -> Result<ChaCha20Rng, TrainError> {
            let mut rng = ChaCha20Rng::from_seed(stream_key(seed, STREAMS[i]));
            rng.set_word_pos(number(&format!("rng.{}", STREAMS[i]))?);
            Ok(rng)
        };
        let best_bits =
            u64::from_str_radix(&get("best_reward")?, 16).map_err(|_| bad("bad best_reward".into()))?;
        Ok(Trainer::from_parts(crate::trainer::Parts {
            env,
            hp,
            seed,
            actor,
            critic,
            adam_actor,
            adam_critic,
            adam_steps: number("adam_steps")? as u64,
            iteration: number("iteration")? as u64,
            rng_actions: stream(1)?,
            rng_minibatches: stream(2)?,
            rng_entropy: stream(3)?,
            observations,
            episode_return,
            best_reward: f64::from_bits(best_bits),
            best_actor,
            best_critic,
        }))
    }
}
