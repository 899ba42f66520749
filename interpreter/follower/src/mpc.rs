//! The CPM Lab's trajectory MPC (§3.3 of the interface notes; `MpcController.cxx`) over any
//! [`Model`]: one control decision, and what the MPC remembers between decisions.
//!
//! This module owns a decision in the lab's order (`MpcController::update`, `:148-195`):
//! filter the battery voltage, predict the state over the actuation delay, sample and check
//! the reference window (`window.rs`), optimise — the lab's 20 warm-started gradient steps
//! (`gradient.rs`, [`Solver::Gradient`], what [`MpcConfig::lab`] selects) or an exact QP
//! (`qp.rs`, [`Solver::Qp`], clarabel) — and check the objective; and the input history, the
//! warm start and the filtered battery voltage. It does not pick commands or keep time;
//! `follower.rs` does.
//!
//! # Numbers
//! Fixed by the lab (`MpcController`): control period 20 ms; delay compensation 3 steps
//! with the last applied inputs; Hp = 6 prediction steps of 50 ms, Hu = 3 moves with
//! move blocking `[1, 1, 2, 2, 3, 3]`; reference at `t_now + 60 ms + 50 ms + k·50 ms`,
//! positions only; cost `Σ wₖ²·|p − p_ref|²` with `w = [1, 1, 2, 1, 1, 3]` plus move
//! penalties (0.5 throttle, 0.01 servo, first move against the previous input); rejection
//! when the first point is not before the window, the last point ends before it, |aₓ| or
//! |a_y| > 20 m/s², |κ| > 50 /m at speed > 0.1 m/s, or the objective ≥ 1.5.
//!
//! # The input history, after a rejection too
//! The lab keeps its last three outputs, oldest first: the delay compensation steps the
//! measured state through them (`:474-501`) and the newest is the previous input the first
//! move is penalised against (`:214-215`). `update` shifts them only at its end
//! (`:186-194`), so what a rejection leaves behind depends on where it happens:
//! - **a refused reference shifts nothing**: fewer than two points, the first point not before
//!   the window, the last point before its end, |aₓ| or |a_y| > 20 m/s², |κ| > 50 /m
//!   (`interpolate_reference_trajectory` returns false, and `update` returns before the shift,
//!   `:163-173`). The next accepted decision predicts with the outputs from before the
//!   rejection, however many periods it lasted;
//! - **a large objective shifts the stop outputs**: `optimize_control_inputs` writes the stop
//!   signals into the outputs (`:323-334`) and returns to the shift, so they enter the history
//!   as accepted outputs do;
//! - both reset the optimiser's warm start to 1e-12 (`reset_optimizer`, `:170`, `:332`).
//!
//! cpmx's own rejections sit where the lab would meet the same input: a non-finite state (in
//! the lab a NaN objective, which fails `< 1.5`) and a QP that clarabel does not solve are
//! stops after optimising, as a large objective: warm start reset, stop input shifted in
//! ([`Rejection::shifts_stop_input`]). Stops that the lab's `Controller` makes before it calls
//! its MPC (no command, a stale one, lost IPS; `Controller.cxx:376-395`) never reach the MPC:
//! no shift, no reset, no battery filter step.
//!
//! # Time
//! Stamps are integer nanoseconds as in the lab's messages (`TimeStamp{nanoseconds}`); the
//! window's sample times are the lab's expressions (`window.rs`), and seconds appear only
//! where the lab converts (the Hermite interpolation, `trajectory.rs`).

use std::collections::VecDeque;

use thiserror::Error;

use crate::gradient::{self, GradientResult, WarmStart};
use crate::model::Model;
use crate::qp::{self, QpCache};
use crate::trajectory::Trajectory;
use crate::window;

/// Prediction steps Hp (lab).
pub const PREDICTION_STEPS: usize = 6;
/// Control moves Hu (lab).
pub const CONTROL_MOVES: usize = 3;

/// Move held at each prediction step (lab's blocking `[1, 1, 2, 2, 3, 3]`, 0-based).
pub(crate) const MOVE_OF_STEP: [usize; PREDICTION_STEPS] = [0, 0, 1, 1, 2, 2];

/// Move weights of the lab's grey-box MPC: throttle 0.5, steering servo 0.01.
pub const LAB_MOVE_WEIGHTS: [f64; 2] = [0.5, 0.01];

/// Move weights chosen for the bicycle (speed command [m/s], steering [rad]): the lab's
/// weights carried through the input scales near 0.5 m/s (≈ 6.9 m/s per unit throttle,
/// ≈ 0.54 rad per unit servo), rounded: 0.5/6.9² ≈ 0.01, 0.01/0.54² ≈ 0.03.
pub const BICYCLE_MOVE_WEIGHTS: [f64; 2] = [0.01, 0.03];

/// Tuning and timing of the MPC.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MpcConfig<const NU: usize> {
    /// Period of the vehicle loop [s] (lab: 0.02).
    pub control_period_s: f64,
    /// Control periods of actuation delay compensated by prediction (lab: 3).
    pub delay_steps: usize,
    /// Prediction step [s] (lab: 0.05).
    pub mpc_step_s: f64,
    /// Position weights wₖ, squared in the cost (lab: `[1, 1, 2, 1, 1, 3]`).
    pub position_weights: [f64; PREDICTION_STEPS],
    /// Weight of squared input moves, per input.
    pub move_weights: [f64; NU],
    /// Solutions with an objective at or above this stop the car (lab: 1.5).
    pub max_objective: f64,
    /// Largest |aₓ|, |a_y| of the reference [m/s²] (lab: 20).
    pub max_reference_accel_mps2: f64,
    /// Largest |κ| of the reference [1/m] while faster than the next field (lab: 50).
    pub max_curvature_per_m: f64,
    /// Speed above which curvature is checked [m/s] (lab: 0.1).
    pub curvature_check_speed_mps: f64,
    /// How the moves are found (lab: [`Solver::Gradient`]).
    pub solver: Solver,
    /// Gradient steps per period with [`Solver::Gradient`] (lab: 20).
    pub gradient_iterations: usize,
    /// The battery voltage the filter starts from [V] (lab: 8).
    pub initial_battery_voltage_v: f64,
    /// Gain of the battery voltage's low-pass filter per period (lab: 0.1).
    pub battery_filter_gain: f64,
}

/// The optimiser of the MPC.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Solver {
    /// The lab's: 20 warm-started gradient steps with momentum on the nonlinear model
    /// (`gradient.rs`).
    #[default]
    Gradient,
    /// The exact optimum of the linearised problem (clarabel), with rate limits as constraints.
    Qp,
}

impl<const NU: usize> MpcConfig<NU> {
    /// The lab's numbers with the given move weights.
    pub fn lab(move_weights: [f64; NU]) -> Self {
        Self {
            control_period_s: 0.02,
            delay_steps: 3,
            mpc_step_s: 0.05,
            position_weights: [1.0, 1.0, 2.0, 1.0, 1.0, 3.0],
            move_weights,
            max_objective: 1.5,
            max_reference_accel_mps2: 20.0,
            max_curvature_per_m: 50.0,
            curvature_check_speed_mps: 0.1,
            solver: Solver::Gradient,
            gradient_iterations: gradient::GRADIENT_ITERATIONS,
            initial_battery_voltage_v: 8.0,
            battery_filter_gain: 0.1,
        }
    }
}

/// Why the MPC refuses to drive (the lab then sends its stop signals).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Rejection {
    /// Fewer than two points.
    #[error("trajectory has fewer than two points")]
    TooFewPoints,
    /// The first point is not before the prediction window.
    #[error(
        "the first trajectory point ({first_ns} ns) is in the future (window starts {window_start_ns} ns)"
    )]
    FirstPointInFuture {
        /// Time of the first point [ns].
        first_ns: u64,
        /// Start of the prediction window [ns].
        window_start_ns: u64,
    },
    /// The last point ends before the prediction window does.
    #[error("insufficient lead time: increase it by {missing_ns} ns")]
    InsufficientLeadTime {
        /// How much later the last point must be [ns].
        missing_ns: u64,
    },
    /// The reference accelerates harder than the limit.
    #[error("large acceleration in reference trajectory: {accel_mps2} m/s²")]
    LargeAcceleration {
        /// The offending component [m/s²].
        accel_mps2: f64,
    },
    /// The reference curves more sharply than the limit.
    #[error("large curvature in reference trajectory: {curvature_per_m} /m")]
    LargeCurvature {
        /// The offending curvature [1/m].
        curvature_per_m: f64,
    },
    /// The optimal cost is too large (reference too far from the vehicle).
    #[error("large MPC objective {objective}")]
    LargeObjective {
        /// The objective of the solution.
        objective: f64,
    },
    /// The state estimate holds NaN or infinity.
    #[error("state estimate is not finite")]
    NonFiniteState,
    /// clarabel did not solve the QP.
    #[error("QP solver failed: {status}")]
    SolverFailed {
        /// clarabel's status or setup error.
        status: String,
    },
}

impl Rejection {
    /// Whether the lab shifts its stop outputs into the input history after this rejection:
    /// after optimising (a large objective, `MpcController.cxx:323-334` then `:186-194`; and
    /// cpmx's non-finite state and failed QP, which sit there), not after a refused reference
    /// (`:163-173` return before the shift).
    pub fn shifts_stop_input(&self) -> bool {
        match self {
            Rejection::TooFewPoints
            | Rejection::FirstPointInFuture { .. }
            | Rejection::InsufficientLeadTime { .. }
            | Rejection::LargeAcceleration { .. }
            | Rejection::LargeCurvature { .. } => false,
            Rejection::LargeObjective { .. } | Rejection::NonFiniteState | Rejection::SolverFailed { .. } => {
                true
            }
        }
    }
}

/// One accepted control decision.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution<const NU: usize> {
    /// The input to apply now.
    pub input: [f64; NU],
    /// The cost of the solution on the nonlinear model.
    pub objective: f64,
    /// Predicted positions at the six reference times [m].
    pub predicted_m: [[f64; 2]; PREDICTION_STEPS],
    /// Reference positions at those times [m].
    pub reference_m: [[f64; 2]; PREDICTION_STEPS],
}

/// The MPC with its input history (for delay compensation and the first move's penalty).
#[derive(Debug, Clone)]
pub struct Mpc<M, const NX: usize, const NU: usize> {
    model: M,
    config: MpcConfig<NU>,
    /// The last `delay_steps` applied inputs, oldest first.
    history: VecDeque<[f64; NU]>,
    previous_input: [f64; NU],
    qp: QpCache,
    /// The gradient solver's iterate and momentum.
    warm: WarmStart<NU>,
    /// The newest battery voltage measurement, if the vehicle measures one [V].
    battery_measured_v: Option<f64>,
    /// The low-pass filtered battery voltage the model predicts with [V].
    battery_filtered_v: f64,
}

impl<M: Model<NX, NU>, const NX: usize, const NU: usize> Mpc<M, NX, NU> {
    /// An MPC whose input history is all zeros (as the lab starts).
    pub fn new(model: M, config: MpcConfig<NU>) -> Self {
        Self {
            model,
            history: std::iter::repeat_n([0.0; NU], config.delay_steps).collect(),
            config,
            previous_input: [0.0; NU],
            qp: QpCache::default(),
            warm: WarmStart::reset(),
            battery_measured_v: None,
            battery_filtered_v: config.initial_battery_voltage_v,
        }
    }

    /// The vehicle's battery voltage measurement for the next solve [V] (the lab filters it,
    /// `V ← V + 0.1·(V_meas − V)` from 8 V, and predicts with the filtered value).
    pub fn measure_battery_voltage(&mut self, voltage_v: f64) {
        if voltage_v.is_finite() {
            self.battery_measured_v = Some(voltage_v);
        }
    }

    /// The filtered battery voltage the model predicts with [V].
    pub fn battery_voltage_v(&self) -> f64 {
        self.battery_filtered_v
    }

    /// The model.
    pub fn model(&self) -> &M {
        &self.model
    }

    /// The configuration.
    pub fn config(&self) -> &MpcConfig<NU> {
        &self.config
    }

    /// The last `delay_steps` inputs the MPC decided (stop inputs after a large objective
    /// included), oldest first: what the next decision's delay compensation steps through.
    pub fn input_history(&self) -> impl ExactSizeIterator<Item = &[f64; NU]> + '_ {
        self.history.iter()
    }

    /// The input the next decision's first move is penalised against (the newest in the
    /// history; the lab's `var_u0`).
    pub fn previous_input(&self) -> &[f64; NU] {
        &self.previous_input
    }

    /// The gradient solver's iterate and momentum for the next decision.
    pub fn warm_start(&self) -> &WarmStart<NU> {
        &self.warm
    }

    /// The state after the actuation delay, predicted with the inputs in the history.
    pub fn compensate_delay(&self, state: &[f64; NX]) -> [f64; NX] {
        self.history.iter().fold(*state, |x, u| {
            self.model.step(&x, u, self.config.control_period_s)
        })
    }

    /// One decision of the lab's MPC for `state` (measured at `t_now_ns`) following
    /// `trajectory`: the input to apply, or why the car stops. The input history and the warm
    /// start change as the lab's do (see the module documentation): an accepted input is
    /// shifted in; a refused reference leaves the history as it was; a rejection after
    /// optimising shifts in the model's stop input for `state`; every rejection resets the
    /// warm start.
    ///
    /// The same as [`Mpc::begin`], the pending problem solved alone, then [`Mpc::finish`].
    pub fn solve(
        &mut self,
        t_now_ns: u64,
        state: &[f64; NX],
        trajectory: &Trajectory,
    ) -> Result<Solution<NU>, Rejection> {
        match self.begin(t_now_ns, state, trajectory) {
            Begun::Decided(decision) => decision,
            Begun::Gradient(pending) => {
                let result = self.solve_pending(&pending);
                self.finish(&pending, result)
            }
        }
    }

    /// The first half of [`Mpc::solve`]: the decision up to the gradient solver's iterations,
    /// so that several vehicles' problems can be solved together
    /// ([`crate::solve_lanes`] with [`Mpc::gradient_parts`]) before each [`Mpc::finish`]es
    /// its own. A decision that needs no gradient solve (a refused reference, a non-finite
    /// state, the QP solver) is taken here, its history and warm start updated.
    pub fn begin(
        &mut self,
        t_now_ns: u64,
        state: &[f64; NX],
        trajectory: &Trajectory,
    ) -> Begun<Result<Solution<NU>, Rejection>, NX, NU> {
        match self.prepare(t_now_ns, state, trajectory) {
            Ok(Prepared::Gradient(problem)) => Begun::Gradient(Pending {
                problem,
                state: *state,
            }),
            Ok(Prepared::Solved(solution)) => Begun::Decided(self.conclude(state, self.checked(solution))),
            Err(rejection) => Begun::Decided(self.conclude(state, Err(rejection))),
        }
    }

    /// The pending problem solved by this MPC alone (the lab's 20 gradient steps).
    pub fn solve_pending(&mut self, pending: &Pending<NX, NU>) -> GradientResult<NU> {
        let p = &pending.problem;
        gradient::solve(
            &gradient::ScalarPrediction(&self.model),
            &self.config,
            &p.x0,
            &p.reference_m,
            &p.previous_input,
            &mut self.warm,
        )
    }

    /// What a solve of this MPC's pending problem needs besides the problem: the model, the
    /// configuration and the warm start it updates.
    pub fn gradient_parts(&mut self) -> (&M, &MpcConfig<NU>, &mut WarmStart<NU>) {
        (&self.model, &self.config, &mut self.warm)
    }

    /// The second half of [`Mpc::solve`]: the gradient solver's `result` for `pending`
    /// checked and remembered (objective check, input history, warm start after a rejection).
    pub fn finish(
        &mut self,
        pending: &Pending<NX, NU>,
        result: GradientResult<NU>,
    ) -> Result<Solution<NU>, Rejection> {
        let solution = Solution {
            input: result.moves[0],
            objective: result.objective,
            predicted_m: result.predicted_m,
            reference_m: pending.problem.reference_m,
        };
        self.conclude(&pending.state, self.checked(solution))
    }

    /// Remembers a decision as the lab does at the end of `update`.
    fn conclude(
        &mut self,
        state: &[f64; NX],
        decision: Result<Solution<NU>, Rejection>,
    ) -> Result<Solution<NU>, Rejection> {
        match &decision {
            Ok(solution) => self.shift_history(solution.input),
            Err(rejection) => {
                // `reset_optimizer` (`:170`, `:332`).
                self.warm = WarmStart::reset();
                if rejection.shifts_stop_input() {
                    self.shift_history(self.model.stop_input(state));
                }
            }
        }
        decision
    }

    /// Shifts `input` into the history as the newest output (`MpcController.cxx:186-194`).
    fn shift_history(&mut self, input: [f64; NU]) {
        if self.config.delay_steps > 0 {
            self.history.pop_front();
            self.history.push_back(input);
        }
        self.previous_input = input;
    }

    /// The lab's `update` up to its optimisation: battery filter, reference window, delay
    /// compensation; the QP solved here, the gradient solve's problem handed back.
    fn prepare(
        &mut self,
        t_now_ns: u64,
        state: &[f64; NX],
        trajectory: &Trajectory,
    ) -> Result<Prepared<NX, NU>, Rejection> {
        // Filter the battery voltage (`:156`), whatever follows.
        if let Some(measured) = self.battery_measured_v {
            self.battery_filtered_v += self.config.battery_filter_gain * (measured - self.battery_filtered_v);
            self.model.set_battery_voltage_v(self.battery_filtered_v);
        }

        // Sample and check the reference (`:163-173`).
        let samples = window::reference_window(t_now_ns, trajectory, &self.config)?;

        // Optimise from the delay-compensated state (`:158`, `:178-184`); a non-finite state
        // would give the lab a NaN objective.
        if !state.iter().all(|v| v.is_finite()) {
            return Err(Rejection::NonFiniteState);
        }
        let x0 = self.compensate_delay(state);
        Ok(match self.config.solver {
            Solver::Qp => Prepared::Solved(qp::solve(
                &self.model,
                &self.config,
                &x0,
                &samples,
                &self.previous_input,
                &mut self.qp,
            )?),
            Solver::Gradient => Prepared::Gradient(Problem {
                x0,
                reference_m: samples.map(|s| s.position_m),
                previous_input: self.previous_input,
            }),
        })
    }

    /// The objective check (`:256`, `:323-334`).
    fn checked(&self, solution: Solution<NU>) -> Result<Solution<NU>, Rejection> {
        if solution.objective < self.config.max_objective {
            Ok(solution)
        } else {
            Err(Rejection::LargeObjective {
                objective: solution.objective,
            })
        }
    }
}

/// One vehicle's problem for the gradient solver: what [`gradient::solve`] takes besides the
/// model, the configuration and the warm start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Problem<const NX: usize, const NU: usize> {
    /// The delay-compensated state.
    pub x0: [f64; NX],
    /// The reference positions [m].
    pub reference_m: [[f64; 2]; PREDICTION_STEPS],
    /// The input the first move is penalised against.
    pub previous_input: [f64; NU],
}

/// Where the first half of a decision leaves it ([`Mpc::begin`]: `D` the MPC's decision;
/// `Follower::begin`: the follower's output).
#[derive(Debug, Clone, PartialEq)]
pub enum Begun<D, const NX: usize, const NU: usize> {
    /// Taken without a gradient solve (and remembered).
    Decided(D),
    /// Waiting for the gradient solver: hand its result to [`Mpc::finish`].
    Gradient(Pending<NX, NU>),
}

/// A decision waiting for its gradient solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pending<const NX: usize, const NU: usize> {
    /// What the solver takes besides the model.
    pub problem: Problem<NX, NU>,
    /// The state estimate the decision is for (a rejection's stop input is the model's for it).
    pub state: [f64; NX],
}

/// [`Mpc::prepare`]'s outcome.
enum Prepared<const NX: usize, const NU: usize> {
    Solved(Solution<NU>),
    Gradient(Problem<NX, NU>),
}
