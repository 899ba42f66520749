//! A [`VecEnv`]'s state as bytes, for checkpoints: what `cpmx train --resume` needs to continue
//! every episode exactly where it stopped.
//!
//! Saved per environment: the step counter, the position of its random stream, every agent's
//! running return and its placement (path, point, float32 bicycle state as f64 bits, velocity).
//! Everything else of an environment is a function of these (an agent's short-term reference
//! points come from its path and position, the corners at the start of a step from its
//! state), so [`VecEnv::load_state`] re-places each agent with them as a reset would.
//!
//! Layout (little-endian): the tag `cpmx-env/state/v2`, `E` and `N` as u64, then per
//! environment the counter (u32), the stream's seed (32 bytes) and word position (u128), `N`
//! returns (f32) and `N` agents (path u64, point u64, x, y, yaw, speed, steering, the two
//! velocity components and the previous steering command as f64), then each environment's
//! vehicle stacks and its neighbour layers when the fidelity has them. States of version 1 (no
//! previous steering command, written before the steering-change term existed) load with
//! that command 0, which no other reward term reads.

use cpmx_vehicle::BicycleState;
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

use crate::starts::Placement;
use crate::vec_env::VecEnv;

const TAG: &[u8] = b"cpmx-env/state/v2";
/// The tag of version 1 (same length).
const TAG_V1: &[u8] = b"cpmx-env/state/v1";

/// Bytes per agent: path, point, 8 floats (7 in version 1), the return.
const AGENT_BYTES: usize = 8 + 8 + 8 * 8 + 4;
const AGENT_BYTES_V1: usize = 8 + 8 + 7 * 8 + 4;
/// Bytes per environment besides its agents: counter, seed, word position.
const ENV_BYTES: usize = 4 + 32 + 16;

impl VecEnv {
    /// Everything needed to continue every episode exactly (see the module documentation).
    pub fn save_state(&self) -> Vec<u8> {
        let (e, n) = (self.num_envs(), self.num_agents());
        let mut out = Vec::with_capacity(TAG.len() + 16 + e * (ENV_BYTES + n * AGENT_BYTES));
        out.extend_from_slice(TAG);
        out.extend_from_slice(&(e as u64).to_le_bytes());
        out.extend_from_slice(&(n as u64).to_le_bytes());
        for env in 0..e {
            let (counter, rng, returns, placements, steering) = self.env_parts(env);
            out.extend_from_slice(&counter.to_le_bytes());
            out.extend_from_slice(&rng.get_seed());
            out.extend_from_slice(&rng.get_word_pos().to_le_bytes());
            for r in returns {
                out.extend_from_slice(&r.to_le_bytes());
            }
            for (p, prev_steering_cmd_rad) in placements.into_iter().zip(steering) {
                out.extend_from_slice(&(p.path as u64).to_le_bytes());
                out.extend_from_slice(&(p.point as u64).to_le_bytes());
                let s = p.state;
                for v in [
                    s.x_m,
                    s.y_m,
                    s.yaw_rad,
                    s.speed_mps,
                    s.steering_rad,
                    p.velocity_mps[0],
                    p.velocity_mps[1],
                    prev_steering_cmd_rad,
                ] {
                    out.extend_from_slice(&v.to_bits().to_le_bytes());
                }
            }
        }
        for env in 0..e {
            if let Some(stack) = self.stack_world(env) {
                stack.save(&mut out);
            }
        }
        // The neighbour layers (communication, perception), when the fidelity has them.
        for env in 0..e {
            if let Some(neighbours) = self.env_neighbours(env) {
                neighbours.save(&mut out);
            }
        }
        out
    }

    /// Restores [`VecEnv::save_state`] bytes of an environment of the same sizes and paths.
    /// On an error nothing has changed.
    pub fn load_state(&mut self, bytes: &[u8]) -> Result<(), String> {
        let (e, n) = (self.num_envs(), self.num_agents());
        let mut r = Reader { bytes, at: 0 };
        let version_1 = match r.take(TAG.len())? {
            t if t == TAG => false,
            t if t == TAG_V1 => true,
            _ => return Err("not a cpmx-env state (wrong tag)".into()),
        };
        let (agent_bytes, floats) = if version_1 {
            (AGENT_BYTES_V1, 7)
        } else {
            (AGENT_BYTES, 8)
        };
        let (se, sn) = (r.u64()?, r.u64()?);
        if (se, sn) != (e as u64, n as u64) {
            return Err(format!(
                "the state holds {se} environments of {sn} agents, this scenario has {e} of {n}"
            ));
        }
        let expected = TAG.len() + 16 + e * (ENV_BYTES + n * agent_bytes);
        let stacks = self.has_stacks();
        let neighbours = self.env_neighbours(0).is_some();
        if bytes.len() < expected || (!stacks && !neighbours && bytes.len() != expected) {
            return Err(format!(
                "the state has {} bytes, {expected} expected (truncated or from another version)",
                bytes.len()
            ));
        }
        let paths = self.path_count();
        let mut parsed = Vec::with_capacity(e);
        for _ in 0..e {
            let counter = r.u32()?;
            let seed: [u8; 32] = r.take(32)?.try_into().map_err(|_| "seed".to_string())?;
            let word_pos = r.u128()?;
            let mut rng = ChaCha20Rng::from_seed(seed);
            rng.set_word_pos(word_pos);
            let returns = (0..n).map(|_| r.f32()).collect::<Result<Vec<f32>, String>>()?;
            let mut placements = Vec::with_capacity(n);
            let mut steering = Vec::with_capacity(n);
            for _ in 0..n {
                let path = r.u64()? as usize;
                let point = r.u64()? as usize;
                let mut v = [0.0f64; 8];
                for x in &mut v[..floats] {
                    *x = f64::from_bits(r.u64()?);
                }
                if path >= paths || v.iter().any(|x| !x.is_finite()) {
                    return Err(format!(
                        "an agent on path {path} of {paths} or with a non-finite state"
                    ));
                }
                placements.push(Placement {
                    path,
                    point,
                    state: BicycleState {
                        x_m: v[0],
                        y_m: v[1],
                        yaw_rad: v[2],
                        speed_mps: v[3],
                        steering_rad: v[4],
                    },
                    velocity_mps: [v[5], v[6]],
                });
                steering.push(v[7]);
            }
            parsed.push((counter, rng, returns, placements, steering));
        }
        // The vehicle stacks, replayed aside (nothing changes on an error).
        let mut worlds = Vec::new();
        if stacks {
            for env in 0..e {
                worlds.push(self.load_stack_world(env, &mut r)?);
            }
        }
        let mut layers = Vec::new();
        for env in 0..e {
            if let Some(mut n) = self.env_neighbours(env).cloned() {
                n.load(bytes, &mut r.at)?;
                layers.push(n);
            }
        }
        if r.at != bytes.len() {
            return Err(format!(
                "the state has {} bytes after its vehicle stacks and layers (from another version?)",
                bytes.len() - r.at
            ));
        }
        for (env, (counter, rng, returns, placements, steering)) in parsed.into_iter().enumerate() {
            self.restore_env(env, counter, rng, &returns, &placements, &steering);
        }
        for (env, world) in worlds.into_iter().enumerate() {
            self.set_stack_world(env, world);
        }
        for (env, n) in layers.into_iter().enumerate() {
            self.set_env_neighbours(env, n);
        }
        Ok(())
    }
}

/// Reads little-endian values off a byte slice.
pub(crate) struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    pub(crate) fn take(&mut self, len: usize) -> Result<&'a [u8], String> {
        let end = self.at + len;
        let slice = self
            .bytes
            .get(self.at..end)
            .ok_or_else(|| format!("the state ends at byte {}", self.bytes.len()))?;
        self.at = end;
        Ok(slice)
    }
    pub(crate) fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().map_err(|_| "u32")?))
    }
    pub(crate) fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().map_err(|_| "u64")?))
    }
    pub(crate) fn u128(&mut self) -> Result<u128, String> {
        Ok(u128::from_le_bytes(
            self.take(16)?.try_into().map_err(|_| "u128")?,
        ))
    }
    fn f32(&mut self) -> Result<f32, String> {
        Ok(f32::from_le_bytes(self.take(4)?.try_into().map_err(|_| "f32")?))
    }
    pub(crate) fn f64(&mut self) -> Result<f64, String> {
        let x = f64::from_bits(self.u64()?);
        if x.is_finite() {
            Ok(x)
        } else {
            Err("a non-finite value".into())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::EnvConfig;

    impl VecEnv {
        /// Every agent's previous steering command, environment by environment.
        fn envs_prev_steering(&self) -> Vec<f64> {
            (0..self.num_envs()).flat_map(|e| self.env_parts(e).4).collect()
        }
    }

    fn map_paths() -> Vec<cpmx_world::ReferencePath> {
        let map = cpmx_testdata::reference_file("maps/cpm.xml");
        crate::sigmarl_intersection_paths(&map).expect("the CPM Lab map of SigmaRL's reference data")
    }

    fn small_env(envs: usize, seed: u64) -> VecEnv {
        let mut config = EnvConfig::default();
        config.scenario.envs = envs;
        // A term that remembers the previous action, so the state must carry it.
        config.reward.steering_change = Some(crate::config::SteeringChangeTerm {
            penalty: -0.02,
            threshold_rad: 0.05,
        });
        VecEnv::new(config, &map_paths(), seed).expect("environment")
    }

    fn actions(step: usize, len: usize) -> Vec<f32> {
        (0..len)
            .map(|i| {
                if i % 2 == 0 {
                    0.6 + 0.05 * ((i + step) % 5) as f32
                } else {
                    0.1 * (((i * 7 + step) % 9) as f32 - 4.0) / 4.0
                }
            })
            .collect()
    }

    #[test]
    fn a_restored_environment_continues_exactly() {
        let mut a = small_env(3, 5);
        let len = a.num_envs() * a.num_agents() * 2;
        for step in 0..40 {
            a.step(&actions(step, len));
        }
        let saved = a.save_state();
        // Another environment (other seed, other history) takes the state over.
        let mut b = small_env(3, 99);
        b.step(&actions(3, len));
        b.load_state(&saved).expect("loads");
        assert_eq!(b.save_state(), saved);
        for step in 40..200 {
            let (ra, rb) = (a.step(&actions(step, len)), b.step(&actions(step, len)));
            assert_eq!(ra, rb, "step {step}");
        }
    }

    #[test]
    fn version_1_states_load_with_no_previous_steering_command() {
        let mut env = small_env(2, 3);
        let len = env.num_envs() * env.num_agents() * 2;
        for step in 0..5 {
            env.step(&actions(step, len));
        }
        // Version 2 with every agent's last float cut out is version 1.
        let v2 = env.save_state();
        let n = env.num_agents();
        let mut v1 = TAG_V1.to_vec();
        let mut at = TAG.len();
        v1.extend_from_slice(&v2[at..at + 16]);
        at += 16;
        for _ in 0..env.num_envs() {
            let head = ENV_BYTES + 4 * n;
            v1.extend_from_slice(&v2[at..at + head]);
            at += head;
            for _ in 0..n {
                v1.extend_from_slice(&v2[at..at + AGENT_BYTES_V1 - 4]);
                at += AGENT_BYTES - 4;
            }
        }
        assert_eq!(at, v2.len());
        let mut restored = small_env(2, 8);
        restored.load_state(&v1).expect("version 1 loads");
        assert!(restored.envs_prev_steering().iter().all(|&c| c == 0.0));
        assert!(env.envs_prev_steering().iter().any(|&c| c != 0.0));
        assert_eq!(restored.placements(1), env.placements(1));
    }

    #[test]
    fn damaged_states_are_refused_and_change_nothing() {
        let mut env = small_env(3, 1);
        let saved = env.save_state();
        let before = env.save_state();
        for bad in [
            &saved[..saved.len() - 3],
            &saved[..10],
            b"cpmx-env/state/v9 and more".as_slice(),
        ] {
            assert!(env.load_state(bad).is_err());
            assert_eq!(env.save_state(), before);
        }
        let mut two = small_env(2, 1);
        let message = two.load_state(&saved).expect_err("sizes differ");
        assert!(message.contains("3 environments"), "{message}");
    }
}
