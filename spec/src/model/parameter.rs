//! Numeric parameters of simulated layers: a number, or a distribution (domain randomisation,
//! spec-language.md "Training"). A spec's [`SimulatedFidelity`] holds [`Parameter`]s; an
//! engine runs a [`DrawnFidelity`], every parameter a number, made by
//! [`SimulatedFidelity::draw`] once per run (`cpmx run`) or per episode (`cpmx train`) from the
//! run's random streams. This module owns the names of the parameters (as a run records its
//! draws), their valid ranges (as the schema states them for numbers), and the order in which
//! they are drawn.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::fidelity::{
    ActuationLayer, ActuationModel, CommunicationLayer, DynamicsLayer, GreyBoxModel, PerceptionLayer,
    SensingLayer, SensingModel, SimulatedFidelity,
};

/// A layer parameter: a number, or a distribution drawn per run (`cpmx run`) and per episode
/// (`cpmx train`), or a sweep of numbers (see Sweeps).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum Parameter {
    /// The value.
    Fixed(f64),
    /// A distribution of values.
    Drawn(Distribution),
}

/// A distribution of a layer parameter.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum Distribution {
    /// `{uniform: [low, high]}`: uniform between `low` < `high`, both in the parameter's range.
    Uniform([f64; 2]),
    /// `{normal: {mean: m, std: s}}`: normal with `s` > 0 and `m` in the parameter's range; a
    /// draw outside the range is drawn again (a truncated normal).
    Normal(NormalDistribution),
}

impl std::fmt::Display for Distribution {
    /// As a spec writes it: `uniform [40, 120]`, `normal (mean 1, std 0.05)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Distribution::Uniform([low, high]) => write!(f, "uniform [{low}, {high}]"),
            Distribution::Normal(NormalDistribution { mean, std }) => {
                write!(f, "normal (mean {mean}, std {std})")
            }
        }
    }
}

/// The parameters of a normal distribution.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NormalDistribution {
    /// The mean.
    pub mean: f64,
    /// The standard deviation (> 0).
    pub std: f64,
}

/// The values a parameter may take: `min` (excluded when `min_exclusive`) to `max`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParameterRange {
    /// The lower bound.
    pub min: f64,
    /// Whether `min` itself is excluded.
    pub min_exclusive: bool,
    /// The upper bound (included).
    pub max: f64,
}

impl ParameterRange {
    const ANY: Self = Self::closed(f64::NEG_INFINITY, f64::INFINITY);
    const NON_NEGATIVE: Self = Self::closed(0.0, f64::INFINITY);

    const fn closed(min: f64, max: f64) -> Self {
        Self {
            min,
            min_exclusive: false,
            max,
        }
    }

    const fn above(min: f64, max: f64) -> Self {
        Self {
            min,
            min_exclusive: true,
            max,
        }
    }

    /// Whether `value` is in the range.
    pub fn contains(&self, value: f64) -> bool {
        let above = if self.min_exclusive {
            value > self.min
        } else {
            value >= self.min
        };
        above && value <= self.max
    }
}

impl std::fmt::Display for ParameterRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let open = if self.min_exclusive { '(' } else { '[' };
        let bound = |v: f64| {
            if v.is_infinite() {
                if v > 0.0 {
                    "inf".to_owned()
                } else {
                    "-inf".to_owned()
                }
            } else {
                v.to_string()
            }
        };
        write!(f, "{open}{}, {}]", bound(self.min), bound(self.max))
    }
}

/// A fidelity as an engine runs it: every layer parameter a number.
pub type DrawnFidelity = SimulatedFidelity<f64>;

/// One parameter of a fidelity as [`SimulatedFidelity::parameters`] lists it.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedParameter {
    /// The key path below the fidelity, as a run records it: `actuation.delay_ms`,
    /// `dynamics.parameters.3` (0-based).
    pub name: String,
    /// The values it may take.
    pub range: ParameterRange,
    /// How the spec gives it.
    pub value: Parameter,
}

impl<P: Copy> SimulatedFidelity<P> {
    /// The same fidelity with every parameter replaced by `f(name, range, parameter)`, called
    /// in a fixed order: dynamics, sensing, actuation, fields as declared.
    fn map_parameters<Q>(&self, f: &mut impl FnMut(&str, ParameterRange, P) -> Q) -> SimulatedFidelity<Q> {
        let dynamics = match &self.dynamics {
            DynamicsLayer::Kinematic(k) => DynamicsLayer::Kinematic(*k),
            DynamicsLayer::GreyBox(g) => DynamicsLayer::GreyBox(GreyBoxModel {
                parameters: std::array::from_fn(|i| {
                    f(
                        &format!("dynamics.parameters.{i}"),
                        ParameterRange::ANY,
                        g.parameters[i],
                    )
                }),
                euler_step_s: f(
                    "dynamics.euler_step_s",
                    ParameterRange::above(0.0, 1.0),
                    g.euler_step_s,
                ),
                battery_voltage_v: f(
                    "dynamics.battery_voltage_v",
                    ParameterRange::above(0.0, 20.0),
                    g.battery_voltage_v,
                ),
            }),
        };
        let sensing = self.sensing.as_ref().map(|layer| match layer {
            SensingLayer::Ideal(k) => SensingLayer::Ideal(*k),
            SensingLayer::Model(s) => SensingLayer::Model(SensingModel {
                rate_hz: f("sensing.rate_hz", ParameterRange::above(0.0, 1000.0), s.rate_hz),
                latency_ms: f(
                    "sensing.latency_ms",
                    ParameterRange::closed(0.0, 10000.0),
                    s.latency_ms,
                ),
                noise_position_m: f(
                    "sensing.noise_position_m",
                    ParameterRange::NON_NEGATIVE,
                    s.noise_position_m,
                ),
                noise_yaw_rad: f(
                    "sensing.noise_yaw_rad",
                    ParameterRange::NON_NEGATIVE,
                    s.noise_yaw_rad,
                ),
                drop_probability: f(
                    "sensing.drop_probability",
                    ParameterRange::closed(0.0, 1.0),
                    s.drop_probability,
                ),
                fusion_gain: f(
                    "sensing.fusion_gain",
                    ParameterRange::closed(0.0, 1.0),
                    s.fusion_gain,
                ),
            }),
        });
        let actuation = self.actuation.as_ref().map(|layer| match layer {
            ActuationLayer::Ideal(k) => ActuationLayer::Ideal(*k),
            ActuationLayer::Model(a) => ActuationLayer::Model(ActuationModel {
                delay_ms: f(
                    "actuation.delay_ms",
                    ParameterRange::closed(0.0, 10000.0),
                    a.delay_ms,
                ),
            }),
        });
        let communication = self.communication.as_ref().map(|c| c.map_parameters(f));
        let perception = self.perception.as_ref().map(|p| p.map_parameters(f));
        SimulatedFidelity {
            control: self.control,
            dynamics,
            sensing,
            actuation,
            follower: self.follower,
            communication,
            perception,
            safety: self.safety.clone(),
        }
    }
}

impl<P: Copy> CommunicationLayer<P> {
    /// The layer with every given parameter replaced by `f(name, range, parameter)`, fields
    /// as declared (parameters left out stay out: their defaults are not drawn).
    pub(crate) fn map_parameters<Q>(
        &self,
        f: &mut impl FnMut(&str, ParameterRange, P) -> Q,
    ) -> CommunicationLayer<Q> {
        let mut map = |name: &str, range, value: Option<P>| value.map(|v| f(name, range, v));
        CommunicationLayer {
            latency_ms: map(
                "communication.latency_ms",
                ParameterRange::closed(0.0, 60000.0),
                self.latency_ms,
            ),
            rate_hz: map(
                "communication.rate_hz",
                ParameterRange::above(0.0, 1000.0),
                self.rate_hz,
            ),
            drop_probability: map(
                "communication.drop_probability",
                ParameterRange::closed(0.0, 1.0),
                self.drop_probability,
            ),
            range_m: map(
                "communication.range_m",
                ParameterRange::above(0.0, f64::INFINITY),
                self.range_m,
            ),
            max_age_ms: map(
                "communication.max_age_ms",
                ParameterRange::NON_NEGATIVE,
                self.max_age_ms,
            ),
        }
    }
}

impl<P: Copy> PerceptionLayer<P> {
    /// The layer with every given parameter replaced by `f(name, range, parameter)`, fields
    /// as declared.
    pub(crate) fn map_parameters<Q>(
        &self,
        f: &mut impl FnMut(&str, ParameterRange, P) -> Q,
    ) -> PerceptionLayer<Q> {
        let mut map = |name: &str, range, value: Option<P>| value.map(|v| f(name, range, v));
        PerceptionLayer {
            range_m: map(
                "perception.range_m",
                ParameterRange::above(0.0, f64::INFINITY),
                self.range_m,
            ),
            field_of_view_deg: map(
                "perception.field_of_view_deg",
                ParameterRange::above(0.0, 360.0),
                self.field_of_view_deg,
            ),
            noise_position_m: map(
                "perception.noise_position_m",
                ParameterRange::NON_NEGATIVE,
                self.noise_position_m,
            ),
            noise_yaw_rad: map(
                "perception.noise_yaw_rad",
                ParameterRange::NON_NEGATIVE,
                self.noise_yaw_rad,
            ),
            detection_probability: map(
                "perception.detection_probability",
                ParameterRange::closed(0.0, 1.0),
                self.detection_probability,
            ),
        }
    }
}

impl PerceptionLayer<Parameter> {
    /// The layer with every distribution replaced by `draw(name, distribution, range)`.
    pub fn draw(
        &self,
        mut draw: impl FnMut(&str, &Distribution, ParameterRange) -> f64,
    ) -> PerceptionLayer<f64> {
        self.map_parameters(&mut |name, range, value| match value {
            Parameter::Fixed(v) => v,
            Parameter::Drawn(d) => draw(name, &d, range),
        })
    }
}

impl CommunicationLayer<Parameter> {
    /// Every given parameter, in the order they are drawn.
    pub fn parameters(&self) -> Vec<NamedParameter> {
        let mut all = Vec::new();
        self.map_parameters(&mut |name, range, value| {
            all.push(NamedParameter {
                name: name.to_owned(),
                range,
                value,
            });
        });
        all
    }

    /// The layer with every distribution replaced by `draw(name, distribution, range)`.
    pub fn draw(
        &self,
        mut draw: impl FnMut(&str, &Distribution, ParameterRange) -> f64,
    ) -> CommunicationLayer<f64> {
        self.map_parameters(&mut |name, range, value| match value {
            Parameter::Fixed(v) => v,
            Parameter::Drawn(d) => draw(name, &d, range),
        })
    }
}

impl SimulatedFidelity<Parameter> {
    /// Every numeric parameter of the layers, in the order they are drawn.
    pub fn parameters(&self) -> Vec<NamedParameter> {
        let mut all = Vec::new();
        self.map_parameters(&mut |name, range, value| {
            all.push(NamedParameter {
                name: name.to_owned(),
                range,
                value,
            });
        });
        all
    }

    /// Whether some parameter is a distribution.
    pub fn is_randomised(&self) -> bool {
        self.parameters()
            .iter()
            .any(|p| matches!(p.value, Parameter::Drawn(_)))
    }

    /// The fidelity with every distribution replaced by `draw(name, distribution, range)`,
    /// called in the order of [`SimulatedFidelity::parameters`]; numbers stay as written.
    pub fn draw(&self, mut draw: impl FnMut(&str, &Distribution, ParameterRange) -> f64) -> DrawnFidelity {
        self.map_parameters(&mut |name, range, value| match value {
            Parameter::Fixed(v) => v,
            Parameter::Drawn(d) => draw(name, &d, range),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Control, FollowerSpec};
    use serde_json::Value;

    fn every_layer() -> SimulatedFidelity {
        let p = Parameter::Fixed(0.5);
        SimulatedFidelity {
            control: Control::Trajectory,
            dynamics: DynamicsLayer::GreyBox(GreyBoxModel {
                parameters: [p; 10],
                euler_step_s: p,
                battery_voltage_v: p,
            }),
            sensing: Some(SensingLayer::Model(SensingModel {
                rate_hz: p,
                latency_ms: p,
                noise_position_m: p,
                noise_yaw_rad: p,
                drop_probability: p,
                fusion_gain: p,
            })),
            actuation: Some(ActuationLayer::Model(ActuationModel { delay_ms: p })),
            follower: Some(FollowerSpec::default()),
            communication: Some(CommunicationLayer {
                latency_ms: Some(p),
                rate_hz: Some(p),
                drop_probability: Some(p),
                range_m: Some(p),
                max_age_ms: Some(p),
            }),
            perception: Some(PerceptionLayer {
                range_m: Some(p),
                field_of_view_deg: Some(p),
                noise_position_m: Some(p),
                noise_yaw_rad: Some(p),
                detection_probability: Some(p),
            }),
            safety: None,
        }
    }

    /// The ranges that `cpmx validate` holds distributions to are the ones the schema states
    /// for numbers.
    #[test]
    fn ranges_agree_with_the_schema() {
        let schema = serde_json::to_value(schemars::schema_for!(SimulatedFidelity)).unwrap();
        let parameters = every_layer().parameters();
        assert_eq!(parameters.len(), 10 + 2 + 6 + 1 + 5 + 5);
        for p in parameters {
            let (layer, field) = p.name.split_once('.').unwrap();
            let def = match layer {
                "dynamics" => "GreyBoxModel",
                "sensing" => "SensingModel",
                "communication" => "CommunicationLayer",
                "perception" => "PerceptionLayer",
                _ => "ActuationModel",
            };
            let field = field.split('.').next().unwrap();
            let property = &schema["$defs"][def]["properties"][field];
            assert!(property.is_object(), "{} not in the schema", p.name);
            let number = |key: &str| property.get(key).and_then(Value::as_f64);
            let (min, min_exclusive) = match (number("minimum"), number("exclusiveMinimum")) {
                (Some(m), None) => (m, false),
                (None, Some(m)) => (m, true),
                (None, None) => (f64::NEG_INFINITY, false),
                both => panic!("{}: {both:?}", p.name),
            };
            let max = number("maximum").unwrap_or(f64::INFINITY);
            assert_eq!(
                p.range,
                ParameterRange {
                    min,
                    min_exclusive,
                    max
                },
                "{}",
                p.name
            );
        }
    }

    #[test]
    fn draws_replace_distributions_in_order_and_keep_numbers() {
        let mut fidelity = every_layer();
        if let Some(ActuationLayer::Model(a)) = &mut fidelity.actuation {
            a.delay_ms = Parameter::Drawn(Distribution::Uniform([40.0, 120.0]));
        }
        if let DynamicsLayer::GreyBox(g) = &mut fidelity.dynamics {
            g.parameters[3] =
                Parameter::Drawn(Distribution::Normal(NormalDistribution { mean: 2.0, std: 0.1 }));
        }
        assert!(fidelity.is_randomised());
        assert!(!every_layer().is_randomised());
        let mut asked = Vec::new();
        let drawn = fidelity.draw(|name, _, _| {
            asked.push(name.to_owned());
            asked.len() as f64
        });
        assert_eq!(asked, ["dynamics.parameters.3", "actuation.delay_ms"]);
        let DynamicsLayer::GreyBox(g) = &drawn.dynamics else {
            panic!()
        };
        assert_eq!(
            (g.parameters[3], g.parameters[4], g.euler_step_s),
            (1.0, 0.5, 0.5)
        );
        let Some(ActuationLayer::Model(a)) = &drawn.actuation else {
            panic!()
        };
        assert_eq!(a.delay_ms, 2.0);
    }
}
