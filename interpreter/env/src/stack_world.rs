//! Training through the lab's control architecture (`control: trajectory`): one environment's
//! vehicles as `cpmx-stack` vehicle stacks (plant, actuation delay, on-car sensing, the 50 Hz
//! MPC follower) driven by the planner, as `cpmx run`'s twin engine drives them.
//!
//! An environment step is one planning period. The learner's action is the policy's decision
//! on the observation of the states the vehicles *report* (listed by the middleware, at least
//! 60 ms old); the planner rolls it out over Hc with the current actor's mean actions on the
//! predicted states (the lookahead; with `lookahead: hold`, the learner's action held for all
//! of Hc), holds the speed and brings the steering to zero until Hp;
//! each vehicle follows its trajectory, anchored at its state's time, for the period. Rewards,
//! collisions and resets use the true states after the period; the next observation the
//! reported ones. A vehicle placed by a reset is a new stack at rest in its start (follower,
//! delay line and localisation in their initial state); a whole-environment reset first draws
//! the episode's fidelity when it is randomised.
//!
//! Randomness: the environment's `train/randomisation/<e>` stream draws each episode's
//! fidelity and each placed vehicle's sensing seed.
//!
//! Checkpoints: a vehicle stack's state is a function of its start, its sensing seed and the
//! trajectories it received (with the ticks they arrived at), so a checkpoint stores those and
//! a restore replays them. Times are the vehicles' nanosecond clock (`cpmx_stack::RUN_START_NS`
//! when a vehicle is placed); a checkpoint holds them as f64 seconds since the placement, as it
//! always did, and a restore rounds them back to whole nanoseconds (exact for any episode
//! shorter than a month).

use cpmx_follower::TrajectoryPoint;
use cpmx_planner::{CommandFilter, Planner, PlannerParams};
use cpmx_policy::{AgentPaths, MlpPolicy, Policy};
use cpmx_safety::layer::LayerFilter;
use cpmx_spec::model::{DrawnFidelity, Lookahead, SimulatedFidelity};
use cpmx_stack::{
    CONTROL_PERIOD_NS, CONTROL_PERIOD_S, InitialState, RUN_START_NS, StampedState, VehicleStack, anchor_ns,
    control_periods, max_state_age_ns, step_together, trajectory_points,
};
use cpmx_vehicle::{BicycleState, Command, Footprint, KinematicBicycle, VehicleParams, footprint_corners};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha20Rng;

use crate::starts::Placement;

/// The lab's control architecture around the environments' vehicles.
#[derive(Debug, Clone, PartialEq)]
pub struct StackPlant {
    /// The fidelity's layers (a `control: trajectory` fidelity; parameters may be
    /// distributions, drawn per episode).
    pub fidelity: SimulatedFidelity,
    /// Hc, Hp and the rule after Hc.
    pub planner: PlannerParams,
    /// What fills Hc after the learner's action: the actor handed over by
    /// [`crate::VecEnv::set_actor`] (mean actions), or the learner's action held.
    pub lookahead: Lookahead,
}

impl StackPlant {
    /// Names of the randomised parameters, in drawing order (the learning curve's columns).
    pub fn randomised_parameters(&self) -> Vec<String> {
        self.fidelity
            .parameters()
            .into_iter()
            .filter(|p| matches!(p.value, cpmx_spec::model::Parameter::Drawn(_)))
            .map(|p| p.name)
            .collect()
    }

    /// Whether the plant can run: `dt` a whole number of control periods, a horizon that
    /// covers the vehicles' reference window.
    pub(crate) fn check(&self, dt_s: f64) -> Result<usize, String> {
        let substeps = control_periods(dt_s)
            .ok_or_else(|| format!("`dt` must be a multiple of the vehicles' {CONTROL_PERIOD_S} s period"))?;
        if self.planner.control_horizon == 0 || self.planner.prediction_horizon < self.planner.control_horizon
        {
            return Err("the planner needs 1 <= Hc <= Hp".into());
        }
        Ok(substeps)
    }
}

/// One vehicle of an environment.
#[derive(Debug)]
struct StackVehicle {
    stack: VehicleStack,
    /// Where it was placed.
    spawn: InitialState,
    /// Its sensing stream's seed.
    sensing_seed: u64,
    /// Its clock (`RUN_START_NS` when it was placed) [ns].
    clock_ns: u64,
    /// Every trajectory it received, with the tick it arrived at [ns] (replayed on restore).
    received: Vec<(u64, Vec<TrajectoryPoint>)>,
    /// Its follower's periods stopped once commanded, as far as a step has reported them.
    stopped_reported: u64,
}

/// The vehicles of one environment and what drives them.
#[derive(Debug)]
pub(crate) struct StackWorld {
    /// This episode's fidelity.
    fidelity: DrawnFidelity,
    /// What was drawn for it (values in drawing order; empty when nothing is randomised).
    drawn: Vec<f64>,
    /// Whether the last whole reset drew (for the learning curve).
    fresh_draw: bool,
    rng: ChaCha20Rng,
    /// The stream's word position before this episode's draw.
    draw_word_pos: u128,
    vehicles: Vec<StackVehicle>,
    planner: Planner,
    substeps: usize,
    /// The planning period [ns].
    dt_ns: u64,
    max_age_ns: u64,
    /// What each vehicle reports at the current tick (the observation's states).
    listed: Vec<StampedState>,
    /// Corners of the reported states of the previous tick (SigmaRL's lagged corners), none
    /// after a whole reset.
    listed_corners: Option<Vec<Footprint>>,
    /// The current actor with mean actions, for the planner's predicted steps.
    lookahead: Option<MlpPolicy>,
}

impl StackWorld {
    /// What each agent knows of the others when the planner plans the next period.
    pub(crate) fn set_neighbours(&mut self, views: Option<&cpmx_policy::NeighbourViews>) {
        self.planner.set_neighbours(views);
    }

    /// The vehicles of environment `env_index` of a training run with `seed`; placed by the
    /// first whole reset.
    pub(crate) fn new(
        plant: &StackPlant,
        vehicle: VehicleParams,
        dt_s: f64,
        rng: ChaCha20Rng,
    ) -> Result<Self, String> {
        let substeps = plant.check(dt_s)?;
        let dt_ns = substeps as u64 * CONTROL_PERIOD_NS;
        let planner = Planner::new(
            PlannerParams {
                step_s: dt_s,
                ..plant.planner
            },
            vehicle,
        );
        Ok(StackWorld {
            fidelity: plant.fidelity.draw(|_, _, range| range.min),
            drawn: Vec::new(),
            fresh_draw: false,
            rng,
            draw_word_pos: 0,
            vehicles: Vec::new(),
            planner,
            substeps,
            dt_ns,
            max_age_ns: max_state_age_ns(
                u32::try_from(plant.planner.prediction_horizon).unwrap_or(u32::MAX),
                dt_ns,
            ),
            listed: Vec::new(),
            listed_corners: None,
            lookahead: None,
        })
    }

    /// The actor the planner looks ahead with (the learner's current one, mean actions).
    pub(crate) fn set_lookahead(&mut self, policy: MlpPolicy) {
        self.lookahead = Some(policy);
    }

    /// A whole reset: draws the episode's fidelity and places a new vehicle at each placement.
    pub(crate) fn reset_whole(
        &mut self,
        plant: &StackPlant,
        vehicle: VehicleParams,
        placements: &[Placement],
    ) -> Result<(), String> {
        self.draw_word_pos = self.rng.get_word_pos();
        let (fidelity, drawn) = cpmx_stack::draw_fidelity(&plant.fidelity, &mut self.rng);
        self.fidelity = fidelity;
        self.fresh_draw = !drawn.is_empty();
        self.drawn = drawn.into_iter().map(|(_, v)| v).collect();
        self.vehicles.clear();
        for (i, p) in placements.iter().enumerate() {
            let seed = self.rng.next_u64();
            let vehicle = self.spawn(vehicle, p, seed, i)?;
            self.vehicles.push(vehicle);
        }
        self.listed = self
            .vehicles
            .iter()
            .map(|v| v.stack.listed_state(v.clock_ns))
            .collect();
        self.listed_corners = None;
        Ok(())
    }

    /// A single-agent reset: a new vehicle for agent `i` at `placement`.
    pub(crate) fn reset_agent(
        &mut self,
        vehicle: VehicleParams,
        i: usize,
        placement: &Placement,
    ) -> Result<(), String> {
        let seed = self.rng.next_u64();
        self.vehicles[i] = self.spawn(vehicle, placement, seed, i)?;
        self.listed[i] = self.vehicles[i].stack.listed_state(RUN_START_NS);
        Ok(())
    }

    fn spawn(
        &self,
        vehicle: VehicleParams,
        p: &Placement,
        sensing_seed: u64,
        agent: usize,
    ) -> Result<StackVehicle, String> {
        let s = p.state;
        let spawn = InitialState {
            ref_path: p.path,
            x_m: s.x_m,
            y_m: s.y_m,
            yaw_rad: s.yaw_rad,
            speed_mps: s.speed_mps,
        };
        Ok(StackVehicle {
            stack: VehicleStack::new(&self.fidelity, vehicle, &spawn, sensing_seed, agent)?,
            spawn,
            sensing_seed,
            clock_ns: RUN_START_NS,
            received: Vec::new(),
            stopped_reported: 0,
        })
    }

    /// The drawn parameter values if the last whole reset drew them (once: the flag clears).
    pub(crate) fn take_fresh_draw(&mut self) -> Option<&[f64]> {
        std::mem::take(&mut self.fresh_draw).then_some(self.drawn.as_slice())
    }

    /// The states the observation sees: what each vehicle reports at the tick.
    pub(crate) fn observed_states(&self, model: &KinematicBicycle) -> Vec<cpmx_policy::AgentState> {
        self.listed
            .iter()
            .map(|l| cpmx_policy::AgentState::from_bicycle(&l.state, model.velocity_mps(&l.state)))
            .collect()
    }

    /// Corners of the reported states of the previous tick.
    pub(crate) fn previous_corners(&self) -> Option<&[Footprint]> {
        self.listed_corners.as_deref()
    }

    /// A planning period is taken in three parts: [`StackWorld::plan`], the vehicles' loops
    /// ([`StackWorld::loop_vehicles`], stepped with [`step_together`], beside other
    /// environments' vehicles) and [`StackWorld::finish_period`].
    /// The vehicles' 50 Hz loop periods in a planning period.
    pub(crate) fn substeps(&self) -> usize {
        self.substeps
    }

    /// The first half of a planning period: plans from the reported states with `first` as
    /// the policy's decisions and hands every vehicle its trajectory.
    pub(crate) fn plan(
        &mut self,
        first: &[Command],
        paths: &AgentPaths,
        vehicle: &VehicleParams,
        filter: Option<&mut LayerFilter>,
    ) -> Result<(), String> {
        let states: Vec<BicycleState> = self.listed.iter().map(|l| l.state).collect();
        let mut hold = HoldCommands;
        let lookahead: &mut dyn Policy = match self.lookahead.as_mut() {
            Some(policy) => policy,
            None => &mut hold,
        };
        let trajectories = self
            .planner
            .plan_from_commands(
                first,
                lookahead,
                filter.map(|f| f as &mut dyn CommandFilter),
                &states,
                paths,
                0.0,
            )
            .map_err(|e| e.to_string())?;
        // The corners of this tick's reported states lag into the next observation.
        self.listed_corners = Some(
            states
                .iter()
                .map(|s| footprint_corners(vehicle, s.x_m, s.y_m, s.yaw_rad))
                .collect(),
        );
        for ((v, listed), trajectory) in self.vehicles.iter_mut().zip(&self.listed).zip(&trajectories) {
            let anchor = anchor_ns(listed.create_ns, v.clock_ns, self.max_age_ns);
            let points = trajectory_points(trajectory, anchor, self.dt_ns);
            v.stack.receive(points.clone(), v.clock_ns, v.clock_ns);
            v.received.push((v.clock_ns, points));
        }
        Ok(())
    }

    /// Loop period `sub` of the planning period: every vehicle with its clock then, to step
    /// with [`step_together`] (beside other environments' vehicles).
    pub(crate) fn loop_vehicles(&mut self, sub: usize) -> impl Iterator<Item = (&mut VehicleStack, u64)> {
        self.vehicles
            .iter_mut()
            .map(move |v| (&mut v.stack, v.clock_ns + sub as u64 * CONTROL_PERIOD_NS))
    }

    /// The last half of a planning period, after its loops: the vehicles' clocks move on, and
    /// the true states after the period (state, velocity) are returned.
    pub(crate) fn finish_period(&mut self) -> Vec<(BicycleState, [f64; 2])> {
        let mut out = Vec::with_capacity(self.vehicles.len());
        for v in &mut self.vehicles {
            v.clock_ns += self.dt_ns;
            let sample = v.stack.true_sample();
            let along =
                sample.velocity_mps[0] * sample.yaw_rad.cos() + sample.velocity_mps[1] * sample.yaw_rad.sin();
            let speed_mps = sample.velocity_mps[0]
                .hypot(sample.velocity_mps[1])
                .copysign(along);
            out.push((
                BicycleState {
                    x_m: sample.x_m,
                    y_m: sample.y_m,
                    yaw_rad: sample.yaw_rad,
                    speed_mps,
                    steering_rad: sample.steering_rad,
                },
                sample.velocity_mps,
            ));
        }
        self.listed = self
            .vehicles
            .iter()
            .map(|v| v.stack.listed_state(v.clock_ns))
            .collect();
        out
    }

    /// Per vehicle, the 50 Hz periods its follower stopped it in (once commanded: refused,
    /// too old or without positioning) since the last call, into `out`.
    pub(crate) fn take_follower_stopped(&mut self, out: &mut Vec<u32>) {
        out.clear();
        for v in &mut self.vehicles {
            let stopped = v.stack.stops().stopped_once_commanded();
            out.push(u32::try_from(stopped - v.stopped_reported).unwrap_or(u32::MAX));
            v.stopped_reported = stopped;
        }
    }

    /// What a checkpoint stores (see the module documentation).
    pub(crate) fn save(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.rng.get_seed());
        out.extend_from_slice(&self.rng.get_word_pos().to_le_bytes());
        out.extend_from_slice(&self.draw_word_pos.to_le_bytes());
        out.push(u8::from(self.fresh_draw));
        match &self.listed_corners {
            None => out.push(0),
            Some(corners) => {
                out.push(1);
                for c in corners.iter().flatten().flatten() {
                    out.extend_from_slice(&c.to_bits().to_le_bytes());
                }
            }
        }
        for v in &self.vehicles {
            let s = v.spawn;
            out.extend_from_slice(&(s.ref_path as u64).to_le_bytes());
            for x in [s.x_m, s.y_m, s.yaw_rad, s.speed_mps, since_placed_s(v.clock_ns)] {
                out.extend_from_slice(&x.to_bits().to_le_bytes());
            }
            out.extend_from_slice(&v.sensing_seed.to_le_bytes());
            out.extend_from_slice(&(v.received.len() as u64).to_le_bytes());
            for (tick_ns, points) in &v.received {
                out.extend_from_slice(&since_placed_s(*tick_ns).to_bits().to_le_bytes());
                out.extend_from_slice(&(points.len() as u64).to_le_bytes());
                for p in points {
                    for x in [since_placed_s(p.t_ns), p.x_m, p.y_m, p.vx_mps, p.vy_mps] {
                        out.extend_from_slice(&x.to_bits().to_le_bytes());
                    }
                }
            }
        }
    }

    /// The world [`StackWorld::save`] wrote to `r`, for `agents` vehicles: the episode's
    /// fidelity drawn again from the saved stream position, every vehicle placed at its start
    /// and what it received replayed; the lookahead is this world's.
    pub(crate) fn load(
        &self,
        plant: &StackPlant,
        vehicle: VehicleParams,
        agents: usize,
        r: &mut crate::state::Reader<'_>,
    ) -> Result<StackWorld, String> {
        let seed: [u8; 32] = r.take(32)?.try_into().map_err(|_| "seed")?;
        let word_pos = r.u128()?;
        let draw_word_pos = r.u128()?;
        let fresh_draw = r.u8()? != 0;
        let listed_corners = match r.u8()? {
            0 => None,
            1 => {
                let mut corners = vec![[[0.0; 2]; 4]; agents];
                for c in corners.iter_mut().flatten().flatten() {
                    *c = r.f64()?;
                }
                Some(corners)
            }
            other => return Err(format!("a corner flag of {other}")),
        };
        let mut rng = ChaCha20Rng::from_seed(seed);
        rng.set_word_pos(draw_word_pos);
        let (fidelity, drawn) = cpmx_stack::draw_fidelity(&plant.fidelity, &mut rng);
        rng.set_word_pos(word_pos);
        let mut world = StackWorld {
            fidelity,
            drawn: drawn.into_iter().map(|(_, v)| v).collect(),
            fresh_draw,
            rng,
            draw_word_pos,
            vehicles: Vec::with_capacity(agents),
            planner: self.planner.clone(),
            substeps: self.substeps,
            dt_ns: self.dt_ns,
            max_age_ns: self.max_age_ns,
            listed: Vec::new(),
            listed_corners,
            lookahead: self.lookahead.clone(),
        };
        for agent in 0..agents {
            let ref_path = r.u64()? as usize;
            let [x_m, y_m, yaw_rad, speed_mps, clock_s] = [r.f64()?, r.f64()?, r.f64()?, r.f64()?, r.f64()?];
            let clock_ns = clock_ns_of(clock_s)?;
            let spawn = InitialState {
                ref_path,
                x_m,
                y_m,
                yaw_rad,
                speed_mps,
            };
            let sensing_seed = r.u64()?;
            let count = r.u64()? as usize;
            let mut stack = VehicleStack::new(&world.fidelity, vehicle, &spawn, sensing_seed, agent)?;
            let mut received = Vec::with_capacity(count.min(1 << 16));
            for _ in 0..count {
                let tick_ns = clock_ns_of(r.f64()?)?;
                let n = r.u64()? as usize;
                let mut points = Vec::with_capacity(n.min(1 << 12));
                for _ in 0..n {
                    points.push(TrajectoryPoint {
                        t_ns: clock_ns_of(r.f64()?)?,
                        x_m: r.f64()?,
                        y_m: r.f64()?,
                        vx_mps: r.f64()?,
                        vy_mps: r.f64()?,
                    });
                }
                follow(&mut stack, tick_ns, &points, world.substeps);
                received.push((tick_ns, points));
            }
            // The replayed periods were reported before the checkpoint.
            let stopped_reported = stack.stops().stopped_once_commanded();
            world.vehicles.push(StackVehicle {
                stack,
                spawn,
                sensing_seed,
                clock_ns,
                received,
                stopped_reported,
            });
        }
        world.listed = world
            .vehicles
            .iter()
            .map(|v| v.stack.listed_state(v.clock_ns))
            .collect();
        Ok(world)
    }
}

/// A vehicle receives `points` at `tick_ns` and runs its 50 Hz loop for the period.
fn follow(stack: &mut VehicleStack, tick_ns: u64, points: &[TrajectoryPoint], substeps: usize) {
    stack.receive(points.to_vec(), tick_ns, tick_ns);
    for sub in 0..substeps as u64 {
        step_together([(&mut *stack, tick_ns + sub * CONTROL_PERIOD_NS)]);
    }
}

/// A time of a vehicle's clock as a checkpoint holds it: seconds since the vehicle was placed
/// (negative before).
fn since_placed_s(t_ns: u64) -> f64 {
    (t_ns as f64 - RUN_START_NS as f64) / 1e9
}

/// [`since_placed_s`] the other way, to the nanosecond it came from.
fn clock_ns_of(since_placed_s: f64) -> Result<u64, String> {
    let t_ns = (since_placed_s * 1e9).round() + RUN_START_NS as f64;
    if !(0.0..=9.0e15).contains(&t_ns) {
        return Err(format!("a vehicle time of {since_placed_s} s"));
    }
    Ok(t_ns as u64)
}

/// The lookahead before a learner has handed its actor over, or for good with `lookahead:
/// hold`: the first commands, held.
struct HoldCommands;

impl Policy for HoldCommands {
    fn act(
        &mut self,
        _: &cpmx_policy::ObservationInput<'_>,
        _: &mut [Command],
    ) -> Result<(), cpmx_policy::PolicyError> {
        // The planner's command buffer still holds the previous step's commands.
        Ok(())
    }
    fn reset(&mut self) {}
    fn fork(&mut self) -> Box<dyn Policy> {
        Box::new(HoldCommands)
    }
}
