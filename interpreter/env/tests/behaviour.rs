//! Properties of the environments that do not need SigmaRL's recordings: starts keep the
//! minimum gap and the admissible ranges, results are identical on any number of threads, and
//! the shaping terms SigmaRL's training reward lacks (speed, centre line) follow their
//! definitions.

use cpmx_env::{CentreLineTerm, EnvConfig, SpeedTerm, StepResult, VecEnv, sigmarl_intersection_paths};
use cpmx_world::ReferencePath;
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha20Rng;

fn paths() -> Vec<ReferencePath> {
    sigmarl_intersection_paths(&cpmx_testdata::reference_file("maps/cpm.xml")).expect("map")
}

fn config(envs: usize) -> EnvConfig {
    let mut c = EnvConfig::default();
    c.scenario.envs = envs;
    c
}

/// Uniform random commands in the action box, from their own stream.
fn random_actions(rng: &mut ChaCha20Rng, n: usize) -> Vec<f32> {
    (0..n)
        .flat_map(|_| {
            [
                rng.random_range(-1.0f32..1.0),
                rng.random_range(-0.541_052_04f32..0.541_052_04),
            ]
        })
        .collect()
}

fn rollout(env: &mut VecEnv, steps: usize) -> Vec<StepResult> {
    let mut rng = ChaCha20Rng::seed_from_u64(5);
    let n = env.num_envs() * env.num_agents();
    (0..steps)
        .map(|_| env.step(&random_actions(&mut rng, n)))
        .collect()
}

#[test]
fn results_do_not_depend_on_threads() {
    let paths = paths();
    let mut serial = VecEnv::new(config(8), &paths, 3).unwrap();
    serial.set_parallel(false);
    let mut parallel = VecEnv::new(config(8), &paths, 3).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
    let a = rollout(&mut serial, 150);
    let b = pool.install(|| rollout(&mut parallel, 150));
    assert_eq!(a, b);
    // Random commands crash often: the rollout exercised whole resets.
    assert!(a.iter().map(|r| r.resets.environments).sum::<u64>() > 20);
    // Another seed gives other starts.
    let other = VecEnv::new(config(8), &paths, 4).unwrap();
    assert_ne!(
        other.placements(0),
        VecEnv::new(config(8), &paths, 3).unwrap().placements(0)
    );
}

#[test]
fn returns_accumulate_until_done_and_means_match_the_agents() {
    let mut env = VecEnv::new(config(4), &paths(), 9).unwrap();
    let results = rollout(&mut env, 60);
    let mut running = [0.0f32; 16];
    for r in &results {
        for (k, sum) in running.iter_mut().enumerate() {
            *sum += r.rewards[k];
            assert_eq!(*sum, r.episode_reward[k]);
        }
        for e in 0..4 {
            if r.done[e] {
                running[e * 4..e * 4 + 4].fill(0.0);
            }
        }
        let mean: f64 = r.agents.iter().map(|a| a.terms.progress).sum::<f64>() / 16.0;
        assert!((mean - r.reward_terms.progress).abs() < 1e-12);
        let crashes = r.agents.iter().filter(|a| a.collides_with_boundary).count() as u64;
        assert_eq!(crashes, r.collisions.with_boundary);
        assert!(r.rewards.iter().all(|x| (-1.0..=1.0).contains(x)));
    }
}

/// The speed and centre-line terms, recomputed from the agents' states after the step with the
/// world crate's float64 segment search, agree with the environment's; adding them changes no
/// other term (the reward does not steer the dynamics).
#[test]
fn shaping_terms_follow_their_definitions_and_leave_the_others_alone() {
    let paths = paths();
    let mut shaped_config = config(4);
    shaped_config.reward.speed = Some(SpeedTerm {
        weight: 0.1,
        against_path_factor: 1.5,
    });
    shaped_config.reward.centre_line = Some(CentreLineTerm {
        penalty: -0.02,
        scale_m: 0.0215,
    });
    let mut shaped = VecEnv::new(shaped_config, &paths, 7).unwrap();
    let mut plain = VecEnv::new(config(4), &paths, 7).unwrap();
    let mut rng = ChaCha20Rng::seed_from_u64(11);
    let (mut checked, mut backwards, mut off_centre) = (0, 0, 0);
    for _ in 0..80 {
        let actions = random_actions(&mut rng, 16);
        let before: Vec<_> = (0..4).map(|e| shaped.placements(e)).collect();
        let r = shaped.step(&actions);
        let q = plain.step(&actions);
        for (a, b) in r.agents.iter().zip(&q.agents) {
            assert!(a.terms.centre_line <= 0.0);
            assert_eq!(b.terms.speed, 0.0);
            assert_eq!(b.terms.centre_line, 0.0);
            assert_eq!(
                [
                    a.terms.progress,
                    a.terms.near_boundary,
                    a.terms.collide_agents,
                    a.terms.collide_boundary
                ],
                [
                    b.terms.progress,
                    b.terms.near_boundary,
                    b.terms.collide_agents,
                    b.terms.collide_boundary
                ]
            );
            let sum = a.terms.progress
                + a.terms.near_boundary
                + a.terms.near_agents_ttc
                + a.terms.collide_agents
                + a.terms.collide_boundary
                + a.terms.speed
                + a.terms.centre_line;
            assert!((a.terms.total - sum.clamp(-1.0, 1.0)).abs() < 1e-12);
        }
        for (e, before) in before.iter().enumerate() {
            if r.done[e] {
                continue;
            }
            let after = shaped.placements(e);
            for k in 0..4 {
                let info = &r.agents[e * 4 + k];
                if info.reset {
                    continue;
                }
                let placed = &after[k];
                assert_eq!(placed.path, before[k].path);
                let path = &paths[placed.path];
                let p = [placed.state.x_m, placed.state.y_m];
                let nearest = path.center_line.nearest_segment(p).unwrap();
                let yaw = path.center_line_yaw_rad[nearest.segment];
                let v = placed.velocity_mps;
                let along = v[0] * yaw.cos() + v[1] * yaw.sin();
                let factor = if along < 0.0 { 1.5 } else { 1.0 };
                let speed = 0.1 * factor * along / 1.0;
                assert!(
                    (info.terms.speed - speed).abs() < 1e-5,
                    "speed {} vs {speed}",
                    info.terms.speed
                );
                let centre = -0.02 * nearest.distance_m / 0.0215;
                assert!(
                    (info.terms.centre_line - centre).abs() < 1e-5,
                    "centre {} vs {centre}",
                    info.terms.centre_line
                );
                checked += 1;
                backwards += usize::from(along < 0.0);
                off_centre += usize::from(nearest.distance_m > 0.01);
            }
        }
    }
    // Random commands drive backwards and off the centre line: both branches were exercised.
    assert!(
        checked > 500 && backwards > 50 && off_centre > 50,
        "{checked} {backwards} {off_centre}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, failure_persistence: None, ..ProptestConfig::default() })]

    /// Every placement (whole resets and single-agent resets) keeps the minimum gap to the
    /// agents it must avoid, a start index in [3, n/2) and a speed in [0, 1).
    #[test]
    fn starts_keep_the_gap_and_the_ranges(seed in 0u64..1_000_000) {
        let paths = paths();
        let mut env = VecEnv::new(config(2), &paths, seed).unwrap();
        let mut rng = ChaCha20Rng::seed_from_u64(seed);
        let gap = env.config().scenario.start.min_gap_m;
        for step in 0..40 {
            let r = if step == 0 { None } else { Some(env.step(&random_actions(&mut rng, 8))) };
            for e in 0..2 {
                let now = env.placements(e);
                let whole = step == 0 || r.as_ref().is_some_and(|r| r.done[e]);
                for (i, p) in now.iter().enumerate() {
                    let fresh = whole || r.as_ref().is_some_and(|r| r.agents[e * 4 + i].reset);
                    if !fresh {
                        continue;
                    }
                    let n = paths[p.path].center_line.points.len();
                    prop_assert!(p.point >= 3 && p.point < n / 2);
                    prop_assert!((0.0..1.0).contains(&p.state.speed_mps));
                    // Whole resets: away from the agents placed before; single: from all others.
                    let others: Vec<_> = if whole { now[..i].to_vec() } else {
                        now.iter().enumerate().filter(|(j, _)| *j != i).map(|(_, q)| *q).collect()
                    };
                    for q in others {
                        let d = (p.state.x_m - q.state.x_m).hypot(p.state.y_m - q.state.y_m);
                        prop_assert!(d >= gap - 1e-6, "gap {d} at step {step}");
                    }
                }
            }
        }
    }
}
