//! SigmaRL's observation design (`stdlib:sigmarl`): the 32-value ego-view observation of
//! `ScenarioRoadTraffic` with its parameters as fields and its quirks as explicit options.
//!
//! This module owns the layout and its numerics (f64 geometry, f32 output). It reads states
//! and prepared paths only; it never steps a vehicle and keeps no state between calls.

use cpmx_vehicle::{BicycleState, Footprint, VehicleParams, footprint_corners};

use crate::geometry::{AgentPaths, PreparedPath};

/// What the observation (and any policy) needs to know about one agent at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AgentState {
    /// Centre, x [m].
    pub x_m: f64,
    /// Centre, y [m].
    pub y_m: f64,
    /// Heading [rad] (wrapped or not: only its sine and cosine are used).
    pub yaw_rad: f64,
    /// Signed longitudinal speed [m/s].
    pub speed_mps: f64,
    /// Velocity vector in the map frame [m/s] (SigmaRL observes its norm).
    pub velocity_mps: [f64; 2],
    /// Steering angle [rad] (observed only with [`SigmarlObservation::observe_steering`]).
    pub steering_rad: f64,
}

impl AgentState {
    /// The state of a kinematic bicycle with its map-frame velocity (the velocity is passed in:
    /// engines keep the one their last step produced).
    pub fn from_bicycle(state: &BicycleState, velocity_mps: [f64; 2]) -> Self {
        AgentState {
            x_m: state.x_m,
            y_m: state.y_m,
            yaw_rad: state.yaw_rad,
            speed_mps: state.speed_mps,
            velocity_mps,
            steering_rad: state.steering_rad,
        }
    }

    /// Norm of the velocity vector [m/s] (always >= 0, also when reversing).
    pub fn velocity_norm_mps(&self) -> f64 {
        self.velocity_mps[0].hypot(self.velocity_mps[1])
    }
}

/// What one agent knows of another when a communication or perception layer stands between
/// them (see [`NeighbourViews`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum NeighbourView {
    /// The state the observation is formed from anyway (heard or seen this very step, exactly):
    /// what every agent knows of every other without the layers. In a planner's lookahead it is
    /// the predicted state, as without the layers.
    #[default]
    Exact,
    /// A state heard in an older message or perceived with noise: observed as it is (not
    /// extrapolated), also in a planner's lookahead.
    Known(AgentState),
    /// Neither heard nor seen: left out of the neighbours, as SigmaRL's observation leaves out
    /// agents that are not there (the nearest of the others fill the slots; then the agent
    /// itself at its placeholder distance; then zeros).
    Absent,
}

/// What each agent knows of each other agent, `[observer][other]`: the output of a fidelity's
/// `communication` and `perception` layers (cpmx-sensing). Without them every view is
/// [`NeighbourView::Exact`], which [`ObservationInput::neighbours`] `None` stands for.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NeighbourViews {
    agents: usize,
    views: Vec<NeighbourView>,
}

impl NeighbourViews {
    /// Every agent knows every other exactly.
    pub fn exact(agents: usize) -> Self {
        NeighbourViews {
            agents,
            views: vec![NeighbourView::Exact; agents * agents],
        }
    }

    /// Number of agents.
    pub fn agents(&self) -> usize {
        self.agents
    }

    /// What `observer` knows of `other`.
    pub fn get(&self, observer: usize, other: usize) -> NeighbourView {
        self.views
            .get(observer * self.agents + other)
            .copied()
            .unwrap_or(NeighbourView::Absent)
    }

    /// Sets what `observer` knows of `other`.
    pub fn set(&mut self, observer: usize, other: usize, view: NeighbourView) {
        if let Some(slot) = self.views.get_mut(observer * self.agents + other) {
            *slot = view;
        }
    }

    /// Whether every view is [`NeighbourView::Exact`] (the layers changed nothing).
    pub fn all_exact(&self) -> bool {
        self.views.iter().all(|v| *v == NeighbourView::Exact)
    }
}

/// Everything a policy sees at one step: all agents' states, their prepared reference
/// paths and the vehicle geometry, plus the corners of the previous step for SigmaRL's lag.
#[derive(Debug, Clone, Copy)]
pub struct ObservationInput<'a> {
    /// State of every agent, in agent order.
    pub agents: &'a [AgentState],
    /// Reference path of every agent, in agent order.
    pub paths: &'a AgentPaths,
    /// Geometry of the vehicles (all agents share it).
    pub vehicle: &'a VehicleParams,
    /// Footprint corners of every agent at the previous observation (`None` right after a
    /// reset). Only used by [`BoundaryCorners::LaggedForFirstAgent`].
    pub previous_corners: Option<&'a [Footprint]>,
    /// What each agent knows of the others when a communication or perception layer stands
    /// between them; `None`: every agent knows every other's state exactly.
    pub neighbours: Option<&'a NeighbourViews>,
}

/// Which corners enter the boundary distances.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BoundaryCorners {
    /// SigmaRL's code: agent 0's corner distances are computed before the corners of the step
    /// are updated, so agent 0 (only) uses the previous observation's corners (the current
    /// ones right after a reset).
    #[default]
    LaggedForFirstAgent,
    /// Every agent uses its current corners (what the paper describes).
    Current,
}

/// Parameters of SigmaRL's observation. [`SigmarlObservation::default`] is the configuration
/// the published policies were trained with (32 values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SigmarlObservation {
    /// Number of observed neighbours (the nearest ones by centre distance).
    pub neighbours: usize,
    /// Number of short-term reference points.
    pub reference_points: usize,
    /// Index stride between short-term reference points on the centre line.
    pub reference_point_stride: usize,
    /// Normaliser of positions [m] (SigmaRL: 10 vehicle lengths).
    pub position_norm_m: f64,
    /// Normaliser of speeds [m/s] (SigmaRL: maximum speed).
    pub speed_norm_mps: f64,
    /// Normaliser of distances to centre line, boundaries and other agents [m]
    /// (SigmaRL: 3 lane widths; its own agent-distance normaliser is not used).
    pub distance_norm_m: f64,
    /// Distance an agent has to itself before neighbours are chosen [m]
    /// (SigmaRL: the map diagonal, 6.0208).
    pub own_distance_placeholder_m: f64,
    /// Observe the distance to the own centre line (1 value).
    pub observe_center_line_distance: bool,
    /// Observe the distances to the left and right shared boundaries (2 values).
    pub observe_boundary_distances: bool,
    /// Observe each neighbour's centre distance (1 value per neighbour).
    pub observe_neighbour_distance: bool,
    /// Observe each neighbour's 4 corners (8 values); otherwise its position (2), heading
    /// relative to the own over 2π (1), length and width (2), over the position normaliser.
    pub observe_vertices: bool,
    /// Noise added to every value after normalisation, uniform on [0, this) (SigmaRL 1.2.0's
    /// `is_add_noise`); drawn by the policy's observation memory from its own stream.
    pub uniform_noise: f32,
    /// Observe in the map frame with positions over these `[x, y]` normalisers [m] (SigmaRL's
    /// bird's-eye view): own position, heading over 2π and velocity first, then map-frame
    /// reference points, corners and velocities; `None`: the ego frame.
    pub bird_view_scale_m: Option<[f64; 2]>,
    /// Observe the steering angles (SigmaRL's `is_obs_steering`): the own after the own speed,
    /// each neighbour's after its velocity (1 + `neighbours` values).
    pub observe_steering: bool,
    /// Normaliser of steering angles [rad] (SigmaRL: 2π).
    pub steering_norm_rad: f64,
    /// Which corners enter the boundary distances.
    pub boundary_corners: BoundaryCorners,
    /// Two slots per observed neighbour after everything else, for that neighbour's action
    /// `[speed m/s, steering rad]` (XP-MARL, SigmaRL 1.2.0): the observation leaves them zero
    /// and the policy fills them ([`crate::PrioritizedPolicy`]).
    pub action_slots: bool,
}

impl Default for SigmarlObservation {
    fn default() -> Self {
        SigmarlObservation {
            neighbours: 2,
            reference_points: 3,
            reference_point_stride: 2,
            position_norm_m: 2.2,
            speed_norm_mps: 1.0,
            distance_norm_m: 0.45,
            own_distance_placeholder_m: 6.0208,
            observe_center_line_distance: true,
            observe_boundary_distances: true,
            observe_neighbour_distance: true,
            observe_vertices: true,
            uniform_noise: 0.0,
            bird_view_scale_m: None,
            observe_steering: false,
            steering_norm_rad: std::f64::consts::TAU,
            boundary_corners: BoundaryCorners::LaggedForFirstAgent,
            action_slots: false,
        }
    }
}

/// Errors of an observation call (the caller's buffers or inputs do not fit together).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ObservationError {
    /// The output buffer does not hold `agents * size` values.
    #[error("observation buffer holds {found} values, expected {expected} ({agents} agents x {size})")]
    BufferSize {
        found: usize,
        expected: usize,
        agents: usize,
        size: usize,
    },
    /// The number of reference paths differs from the number of agents.
    #[error("{paths} reference paths for {agents} agents")]
    PathCount { paths: usize, agents: usize },
    /// The previous corners do not cover every agent.
    #[error("previous corners for {found} agents, expected {agents}")]
    CornerCount { found: usize, agents: usize },
    /// The design adds noise and the policy was given no stream to draw it from.
    #[error("the observation adds noise, and the policy has no `observation-noise` stream")]
    NoNoiseStream,
    /// A reference path has fewer than two centre-line or boundary points.
    #[error("reference path {id} has a centre line or shared boundary with fewer than two points")]
    DegeneratePath { id: usize },
}

/// Most neighbours the allocation-free selection supports.
pub const MAX_NEIGHBOURS: usize = 8;

impl SigmarlObservation {
    /// Number of values per agent (32 for the default parameters).
    pub fn size(&self) -> usize {
        let steering = usize::from(self.observe_steering);
        let own = if self.bird_view_scale_m.is_some() { 5 } else { 1 };
        own + steering
            + 2 * self.reference_points
            + usize::from(self.observe_center_line_distance)
            + 2 * usize::from(self.observe_boundary_distances)
            + self.neighbours
                * (self.neighbour_shape() + 2 + steering + usize::from(self.observe_neighbour_distance))
            + self.action_slot_count()
    }

    /// Values that place and shape one neighbour: its corners, or its pose and size.
    fn neighbour_shape(&self) -> usize {
        if self.observe_vertices { 8 } else { 5 }
    }

    /// Number of action slots at the end of each agent's observation (2 per observed neighbour,
    /// or none).
    pub fn action_slot_count(&self) -> usize {
        if self.action_slots { 2 * self.neighbours } else { 0 }
    }

    /// [`SigmarlObservation::observe_all`], also writing which agent each agent observes in
    /// each neighbour slot (`neighbours[i * self.neighbours + k]`, nearest first; `None` where a
    /// slot holds no other agent): the agents whose actions fill its action slots.
    pub fn observe_all_with_neighbours(
        &self,
        input: &ObservationInput<'_>,
        out: &mut [f32],
        neighbours: &mut [Option<usize>],
    ) -> Result<(), ObservationError> {
        let expected = input.agents.len() * self.neighbours;
        if neighbours.len() != expected {
            return Err(ObservationError::BufferSize {
                found: neighbours.len(),
                expected,
                agents: input.agents.len(),
                size: self.neighbours,
            });
        }
        self.observe_checked(input, out, Some(neighbours))
    }

    /// Observations of all agents into `out` (`agents * size()` values, agent-major).
    /// Allocation-free.
    pub fn observe_all(&self, input: &ObservationInput<'_>, out: &mut [f32]) -> Result<(), ObservationError> {
        self.observe_checked(input, out, None)
    }

    fn observe_checked(
        &self,
        input: &ObservationInput<'_>,
        out: &mut [f32],
        mut neighbours: Option<&mut [Option<usize>]>,
    ) -> Result<(), ObservationError> {
        // Check that the inputs fit together.
        let (n, size) = (input.agents.len(), self.size());
        if out.len() != n * size {
            return Err(ObservationError::BufferSize {
                found: out.len(),
                expected: n * size,
                agents: n,
                size,
            });
        }
        if input.paths.len() != n {
            return Err(ObservationError::PathCount {
                paths: input.paths.len(),
                agents: n,
            });
        }
        if let Some(prev) = input.previous_corners
            && prev.len() != n
        {
            return Err(ObservationError::CornerCount {
                found: prev.len(),
                agents: n,
            });
        }
        for path in &input.paths.paths {
            if path.center.is_empty() || path.left_shared.is_empty() || path.right_shared.is_empty() {
                return Err(ObservationError::DegeneratePath { id: path.id });
            }
        }

        let k = self.neighbours;
        for (i, chunk) in out.chunks_exact_mut(size).enumerate() {
            let chosen = neighbours.as_deref_mut().map(|n| &mut n[i * k..(i + 1) * k]);
            self.observe_one(input, i, chunk, chosen);
        }
        Ok(())
    }

    /// Observation of agent `ego` (inputs already checked); `observed` receives the agent in
    /// each neighbour slot.
    fn observe_one(
        &self,
        input: &ObservationInput<'_>,
        ego: usize,
        out: &mut [f32],
        observed: Option<&mut [Option<usize>]>,
    ) {
        let me = &input.agents[ego];
        let path: &PreparedPath = &input.paths.paths[ego];
        let frame = match self.bird_view_scale_m {
            Some(scale) => Frame::Map(scale),
            None => Frame::Ego(EgoFrame::new(me), self.position_norm_m),
        };
        let mut w = Writer { out, at: 0 };

        // Own pose in the map frame, and velocity (ego frame: the speed; map frame: its vector).
        if let Some([sx, sy]) = self.bird_view_scale_m {
            w.push(me.x_m / sx);
            w.push(me.y_m / sy);
            w.push(me.yaw_rad / std::f64::consts::TAU);
            w.push(me.velocity_mps[0] / self.speed_norm_mps);
            w.push(me.velocity_mps[1] / self.speed_norm_mps);
        } else {
            w.push(me.velocity_norm_mps() / self.speed_norm_mps);
        }
        if self.observe_steering {
            w.push(me.steering_rad / self.steering_norm_rad);
        }

        // Short-term reference points, from the closest centre-line point onward.
        let nearest = path.center.nearest([me.x_m, me.y_m]);
        let (center_distance_m, closest_index) = nearest.map_or((0.0, 0), |n| (n.distance_m, n.segment + 1));
        for k in 0..self.reference_points {
            let q = frame.normalised(path.center_point(closest_index + 1 + k * self.reference_point_stride));
            w.push(q[0]);
            w.push(q[1]);
        }

        // Distance to the own centre line.
        if self.observe_center_line_distance {
            w.push(center_distance_m / self.distance_norm_m);
        }

        // Distances to the shared road boundaries: the centre minus half the width, and the corners.
        if self.observe_boundary_distances {
            let corners = match (self.boundary_corners, input.previous_corners) {
                (BoundaryCorners::LaggedForFirstAgent, Some(prev)) if ego == 0 => prev[0],
                _ => footprint_corners(input.vehicle, me.x_m, me.y_m, me.yaw_rad),
            };
            let half_width = input.vehicle.width_m / 2.0;
            for side in [&path.left_shared, &path.right_shared] {
                let centre = side.distance_m([me.x_m, me.y_m]) - half_width;
                let d = corners.iter().map(|&c| side.distance_m(c)).fold(centre, f64::min);
                w.push(d / self.distance_norm_m);
            }
        }

        // Nearest neighbours by centre distance, ascending (the agent itself at the placeholder).
        let mut chosen = [(f64::INFINITY, 0usize); MAX_NEIGHBOURS];
        let k = self.neighbours.min(MAX_NEIGHBOURS);
        // What the agent knows of each other (everything exactly without the layers).
        let view = |j: usize| input.neighbours.map_or(NeighbourView::Exact, |v| v.get(ego, j));
        let state_of = |j: usize| match view(j) {
            NeighbourView::Known(state) if j != ego => state,
            _ => input.agents[j],
        };
        for j in 0..input.agents.len() {
            let d = if j == ego {
                self.own_distance_placeholder_m
            } else if view(j) == NeighbourView::Absent {
                continue;
            } else {
                let other = state_of(j);
                (other.x_m - me.x_m).hypot(other.y_m - me.y_m)
            };
            insert_sorted(&mut chosen[..k], (d, j));
        }
        if let Some(observed) = observed {
            for (slot, &(distance_m, j)) in observed.iter_mut().zip(&chosen[..k]) {
                *slot = (distance_m.is_finite() && j != ego).then_some(j);
            }
            observed.iter_mut().skip(k).for_each(|slot| *slot = None);
        }
        for &(distance_m, j) in chosen[..k].iter().filter(|e| e.0.is_finite()) {
            let other = &state_of(j);
            if self.observe_vertices {
                for c in footprint_corners(input.vehicle, other.x_m, other.y_m, other.yaw_rad) {
                    let q = frame.normalised(c);
                    w.push(q[0]);
                    w.push(q[1]);
                }
            } else {
                let q = frame.normalised([other.x_m, other.y_m]);
                w.push(q[0]);
                w.push(q[1]);
                w.push((other.yaw_rad - me.yaw_rad) / std::f64::consts::TAU);
                w.push(input.vehicle.length_m / self.position_norm_m);
                w.push(input.vehicle.width_m / self.position_norm_m);
            }
            if self.bird_view_scale_m.is_some() {
                w.push(other.velocity_mps[0] / self.speed_norm_mps);
                w.push(other.velocity_mps[1] / self.speed_norm_mps);
            } else {
                let (speed, heading) = (other.velocity_norm_mps(), other.yaw_rad - me.yaw_rad);
                w.push(speed * heading.cos() / self.speed_norm_mps);
                w.push(speed * heading.sin() / self.speed_norm_mps);
            }
            if self.observe_steering {
                w.push(other.steering_rad / self.steering_norm_rad);
            }
            if self.observe_neighbour_distance {
                w.push(distance_m / self.distance_norm_m);
            }
        }
        // More neighbours requested than agents exist (or than supported), and the action
        // slots: zeros.
        w.fill_rest();
    }
}

/// Insert `item` into the ascending list `list` (keeping its length), stable on ties.
fn insert_sorted(list: &mut [(f64, usize)], item: (f64, usize)) {
    let Some(pos) = list.iter().position(|e| item.0 < e.0) else {
        return;
    };
    list[pos..].rotate_right(1);
    list[pos] = item;
}

/// Where observed points are expressed: an agent's ego frame (over the position normaliser), or
/// the map frame (over its x and y normalisers).
enum Frame {
    Ego(EgoFrame, f64),
    Map([f64; 2]),
}

impl Frame {
    fn normalised(&self, p: [f64; 2]) -> [f64; 2] {
        match self {
            Frame::Ego(ego, norm_m) => ego.to_ego(p).map(|v| v / norm_m),
            Frame::Map([sx, sy]) => [p[0] / sx, p[1] / sy],
        }
    }
}

/// The ego frame of an agent: map points relative to its centre, rotated by minus its yaw.
struct EgoFrame {
    origin: [f64; 2],
    cos: f64,
    sin: f64,
}

impl EgoFrame {
    fn new(me: &AgentState) -> Self {
        let (sin, cos) = me.yaw_rad.sin_cos();
        EgoFrame {
            origin: [me.x_m, me.y_m],
            cos,
            sin,
        }
    }

    fn to_ego(&self, p: [f64; 2]) -> [f64; 2] {
        let (dx, dy) = (p[0] - self.origin[0], p[1] - self.origin[1]);
        [dx * self.cos + dy * self.sin, -dx * self.sin + dy * self.cos]
    }
}

/// Sequential writer into one agent's slice.
struct Writer<'a> {
    out: &'a mut [f32],
    at: usize,
}

impl Writer<'_> {
    fn push(&mut self, v: f64) {
        if let Some(slot) = self.out.get_mut(self.at) {
            *slot = v as f32;
        }
        self.at += 1;
    }

    fn fill_rest(&mut self) {
        if let Some(rest) = self.out.get_mut(self.at..) {
            rest.fill(0.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_layout_has_32_values() {
        assert_eq!(SigmarlObservation::default().size(), 32);
    }

    /// With the steering observed: the own angle after the own speed, each neighbour's after
    /// its velocity, over 2π; everything else in place.
    #[test]
    fn steering_is_observed_where_sigmarl_puts_it() {
        let map = cpmx_world::Map::builtin("intersection").unwrap();
        let paths = AgentPaths::new([1, 2, 3].map(|id| map.reference_path(id).unwrap()));
        let agents: Vec<AgentState> = [(0.3, 0.1), (-0.5, -0.2), (1.0, 0.4)]
            .iter()
            .enumerate()
            .map(|(i, &(x, steering_rad))| AgentState {
                x_m: x,
                y_m: 0.2 * i as f64,
                yaw_rad: 0.1,
                speed_mps: 0.5,
                velocity_mps: [0.5, 0.05],
                steering_rad,
            })
            .collect();
        let input = ObservationInput {
            agents: &agents,
            paths: &paths,
            vehicle: &VehicleParams::MU_CAR,
            previous_corners: None,
            neighbours: None,
        };
        let plain = SigmarlObservation::default();
        let steered = SigmarlObservation {
            observe_steering: true,
            ..plain
        };
        assert_eq!(steered.size(), 35);
        let (mut a, mut b) = (vec![0.0; 3 * 32], vec![0.0; 3 * 35]);
        plain.observe_all(&input, &mut a).unwrap();
        steered.observe_all(&input, &mut b).unwrap();
        let (a, b) = (&a[..32], &b[..35]);
        let tau = std::f64::consts::TAU;
        assert_eq!(b[1], (0.1 / tau) as f32);
        // Own part: speed, steering, then as before.
        assert_eq!(b[0], a[0]);
        assert_eq!(b[2..11], a[1..10]);
        // Each neighbour (agent 2 is nearest, then agent 1): 4 corners, velocity, steering,
        // distance.
        assert_eq!(b[11..21], a[10..20]);
        assert_eq!(b[21], (0.4 / tau) as f32);
        assert_eq!(b[22], a[20]);
        assert_eq!(b[23..33], a[21..31]);
        assert_eq!(b[33], (-0.2 / tau) as f32);
        assert_eq!(b[34], a[31]);
    }

    #[test]
    fn insertion_keeps_the_smallest_in_order_and_first_on_ties() {
        let mut l = [(f64::INFINITY, 0); 2];
        for (d, j) in [(3.0, 0), (1.0, 1), (2.0, 2), (1.0, 3)] {
            insert_sorted(&mut l, (d, j));
        }
        assert_eq!(l, [(1.0, 1), (1.0, 3)]);
    }
}
