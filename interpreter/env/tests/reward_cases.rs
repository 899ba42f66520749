//! Agreement with SigmaRL's recorded training steps (`training/reward_cases.json`): the
//! environment replays each recorded segment from its recorded start with the recorded
//! actions, and after every reset takes the recorded reset states (its own draws differ);
//! every reward term, the reward, the running return, every collision and line flag, done,
//! the single-agent resets, the moved states and the observations the policy received agree.

use cpmx_env::{EnvConfig, Placement, StepResult, VecEnv, sigmarl_intersection_paths};
use cpmx_vehicle::BicycleState;
use serde_json::Value;

const TOL: f64 = 1e-5;

fn json(relative: &str) -> Value {
    let text = cpmx_testdata::read_reference(relative);
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{relative}: {e}"))
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn env_of(agents: usize) -> VecEnv {
    let paths = sigmarl_intersection_paths(&cpmx_testdata::reference_file("maps/cpm.xml")).expect("map");
    assert_eq!(paths.len(), 24);
    let mut config = EnvConfig::default();
    config.scenario.envs = 1;
    config.scenario.agents = agents;
    let mut env = VecEnv::new(config, &paths, 0).expect("env");
    env.set_parallel(false);
    env
}

/// Agent `i` of a recorded state object.
fn placement(state: &Value, i: usize) -> Placement {
    Placement {
        path: state["path_id"][i].as_u64().expect("path") as usize,
        point: state["point_id"][i].as_u64().expect("point") as usize,
        state: BicycleState {
            x_m: num(&state["pos"][i][0]),
            y_m: num(&state["pos"][i][1]),
            yaw_rad: num(&state["rot"][i]),
            speed_mps: num(&state["speed"][i]),
            steering_rad: num(&state["steering"][i]),
        },
        velocity_mps: [num(&state["vel"][i][0]), num(&state["vel"][i][1])],
    }
}

fn close(what: &str, got: f64, want: f64) {
    assert!((got - want).abs() <= TOL, "{what}: got {got}, want {want}");
}

fn bools(v: &Value) -> Vec<bool> {
    v.as_array()
        .expect("bools")
        .iter()
        .map(|b| b.as_bool().expect("bool"))
        .collect()
}

fn check_step(name: &str, step: &Value, r: &StepResult, agents: usize, return_offset: &[f64]) {
    let t = step["t"].as_u64().expect("t");
    let reward = &step["reward"];
    let inputs = &step["reward_inputs"];
    let resets: Vec<usize> = step["single_agent_resets"]
        .as_array()
        .expect("resets")
        .iter()
        .map(|v| v.as_u64().expect("agent") as usize)
        .collect();
    let with_boundary = bools(&inputs["collision_with_boundaries"]);
    let (entry, exit) = (
        bools(&inputs["touches_entry_line"]),
        bools(&inputs["touches_exit_line"]),
    );
    for i in 0..agents {
        let at = |what: &str| format!("{name} t={t} agent {i} {what}");
        let info = &r.agents[i];
        let terms = &info.terms;
        close(&at("progress"), terms.progress, num(&reward["progress"][i]));
        close(
            &at("near_boundary"),
            terms.near_boundary,
            num(&reward["near_boundary"][i]),
        );
        close(
            &at("near_agents_ttc"),
            terms.near_agents_ttc,
            num(&reward["near_agents_ttc"][i]),
        );
        // SigmaRL adds each collision penalty (-1) twice; the configured term is the sum (-2).
        close(
            &at("collide_agents"),
            terms.collide_agents,
            2.0 * num(&reward["collide_agents"][i]),
        );
        close(
            &at("collide_boundary"),
            terms.collide_boundary,
            2.0 * num(&reward["collide_boundary"][i]),
        );
        close(
            &at("sum_unclamped"),
            terms.sum_unclamped,
            num(&reward["sum_unclamped"][i]),
        );
        close(&at("total"), terms.total, num(&reward["total"][i]));
        close(
            &at("env_reward"),
            f64::from(r.rewards[i]),
            num(&step["env_reward"][i]),
        );
        close(
            &at("episode_reward"),
            f64::from(r.episode_reward[i]),
            num(&step["episode_reward"][i]) - return_offset[i],
        );
        let with_agents = bools(&inputs["collision_with_agents"][i]).iter().any(|&c| c);
        assert_eq!(
            info.collides_with_agents,
            with_agents,
            "{}",
            at("collision with agents")
        );
        assert_eq!(
            info.collides_with_boundary,
            with_boundary[i],
            "{}",
            at("collision with boundary")
        );
        assert_eq!(
            info.touches_entry_or_exit,
            entry[i] || exit[i],
            "{}",
            at("entry/exit")
        );
        assert_eq!(info.reset, resets.contains(&i), "{}", at("single-agent reset"));
    }
    let done = step["done"]["done"].as_bool().expect("done");
    assert_eq!(r.done[0], done, "{name} t={t} done");
    assert_eq!(r.terminated[0], done, "{name} t={t} terminated");
    assert_eq!(
        step["env_reset"].as_bool(),
        Some(done),
        "{name} t={t}: the collector resets done envs"
    );
}

fn replay(episode: &Value) -> (usize, usize, usize) {
    let name = episode["name"].as_str().expect("name");
    let initial = &episode["initial"];
    let agents = initial["state"]["pos"].as_array().expect("agents").len();
    let mut env = env_of(agents);
    let counter = initial["timer_step"].as_u64().expect("timer") as u32;
    for i in 0..agents {
        env.place(0, i, placement(&initial["state"], i), counter);
    }
    // The recorded returns may start mid-episode: offset until the first whole reset.
    let steps = episode["steps"].as_array().expect("steps");
    let first = &steps[0];
    let mut offset: Vec<f64> = (0..agents)
        .map(|i| num(&first["episode_reward"][i]) - num(&first["env_reward"][i]))
        .collect();
    let (mut env_resets, mut agent_resets, mut observations) = (0, 0, 0);
    let mut next_obs: Option<Vec<f32>> = None;
    for step in steps {
        let t = step["t"].as_u64().expect("t");
        assert_eq!(
            u64::from(env.step_counter(0)),
            step["timer_step_before"].as_u64().expect("timer")
        );
        // The state the action is applied to.
        for (i, p) in env.placements(0).iter().enumerate() {
            close(
                &format!("{name} t={t} x{i}"),
                p.state.x_m,
                num(&step["state"]["pos"][i][0]),
            );
            close(
                &format!("{name} t={t} y{i}"),
                p.state.y_m,
                num(&step["state"]["pos"][i][1]),
            );
        }
        // The observation the policy received (actor episodes).
        if let (Some(obs), Some(ours)) = (step.get("obs"), next_obs.as_ref()) {
            for (k, v) in obs
                .as_array()
                .expect("obs")
                .iter()
                .flat_map(|o| o.as_array().expect("obs"))
                .enumerate()
            {
                close(&format!("{name} t={t} obs[{k}]"), f64::from(ours[k]), num(v));
            }
            observations += 1;
        }
        let actions: Vec<f32> = step["action"]
            .as_array()
            .expect("actions")
            .iter()
            .flat_map(|a| [num(&a[0]) as f32, num(&a[1]) as f32])
            .collect();
        let r = env.step(&actions);
        // The moved states (before any reset) are what the reward saw; check through the terms.
        check_step(name, step, &r, agents, &offset);
        next_obs = Some(r.observations.clone());
        if r.done[0] {
            env_resets += 1;
            offset.fill(0.0);
            for i in 0..agents {
                env.place(0, i, placement(&step["state_after_reset"], i), 0);
            }
            next_obs = Some(env.observe(0));
        } else {
            for i in step["single_agent_resets"].as_array().expect("resets") {
                let i = i.as_u64().expect("agent") as usize;
                agent_resets += 1;
                let counter = env.step_counter(0);
                env.place(0, i, placement(&step["state_after_reset"], i), counter);
            }
        }
        assert_eq!(r.resets.environments, u64::from(r.done[0]));
    }
    (env_resets, agent_resets, observations)
}

#[test]
fn every_recorded_reward_term_flag_and_reset_agrees_with_sigmarl() {
    let root = json("training/reward_cases.json");
    let (mut env_resets, mut agent_resets, mut observations) = (0, 0, 0);
    for episode in root["episodes"].as_array().expect("episodes") {
        let (e, a, o) = replay(episode);
        env_resets += e;
        agent_resets += a;
        observations += o;
    }
    let counts = &root["counts"];
    assert_eq!(env_resets as u64, counts["env_resets"].as_u64().unwrap());
    assert_eq!(
        agent_resets as u64,
        counts["single_agent_resets"].as_u64().unwrap()
    );
    assert!(observations > 100, "{observations} observations compared");
}
