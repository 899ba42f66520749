//! Arithmetic written once for a scalar and for lanes: [`Real`] is what a model's step or a
//! solver needs of its numbers (`+ − × ÷`, comparisons and selects, `√`, and the crate's
//! functions), implemented by `f64` and by [`Lanes`], `L` independent problems side by side.
//!
//! Code generic over `Real` performs, in every lane, the operations the scalar instance
//! performs, in the same order, each rounded once: the lanes give the scalar bits (the crate's
//! invariants). That is how the lab's MPCs of several vehicles are solved together without a
//! second implementation to keep equal to the first.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// A number the generic code computes with: one `f64`, or `L` of them in lanes.
pub trait Real:
    Copy
    + std::fmt::Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// The result of a comparison: `bool`, or one per lane.
    type Mask: Copy;

    /// `value` in every lane.
    fn splat(value: f64) -> Self;
    /// `self < other` (false when either is NaN).
    fn lt(self, other: Self) -> Self::Mask;
    /// `self >= other` (false when either is NaN).
    fn ge(self, other: Self) -> Self::Mask;
    /// `self == other`.
    fn eq(self, other: Self) -> Self::Mask;
    /// `when ? then : otherwise`, lane by lane.
    fn select(when: Self::Mask, then: Self, otherwise: Self) -> Self;
    /// |self|.
    fn abs(self) -> Self;
    /// The correctly rounded square root.
    fn sqrt(self) -> Self;
    /// `f64::clamp`'s rule: below `low` gives `low`, above `high` gives `high`, NaN stays NaN.
    fn clamp(self, low: Self, high: Self) -> Self;
    /// sin and cos ([`crate::sin_cos`]).
    fn sin_cos(self) -> (Self, Self);
    /// [`crate::tan`].
    fn tan(self) -> Self;
    /// [`crate::atan`].
    fn atan(self) -> Self;
    /// `atan2(self, x)` ([`crate::atan2`]).
    fn atan2(self, x: Self) -> Self;
    /// [`crate::hypot`].
    fn hypot(self, other: Self) -> Self;
    /// [`crate::exp`].
    fn exp(self) -> Self;
    /// [`crate::pow`].
    fn pow(self, exponent: Self) -> Self;
}

impl Real for f64 {
    type Mask = bool;

    #[inline(always)]
    fn splat(value: f64) -> Self {
        value
    }
    #[inline(always)]
    fn lt(self, other: Self) -> bool {
        self < other
    }
    #[inline(always)]
    fn ge(self, other: Self) -> bool {
        self >= other
    }
    #[inline(always)]
    fn eq(self, other: Self) -> bool {
        self == other
    }
    #[inline(always)]
    fn select(when: bool, then: Self, otherwise: Self) -> Self {
        if when { then } else { otherwise }
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn clamp(self, low: Self, high: Self) -> Self {
        clamp(self, low, high)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        crate::sin_cos(self)
    }
    #[inline(always)]
    fn tan(self) -> Self {
        crate::tan(self)
    }
    #[inline(always)]
    fn atan(self) -> Self {
        crate::atan(self)
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        crate::atan2(self, x)
    }
    #[inline(always)]
    fn hypot(self, other: Self) -> Self {
        crate::hypot(self, other)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        crate::exp(self)
    }
    #[inline(always)]
    fn pow(self, exponent: Self) -> Self {
        crate::pow(self, exponent)
    }
}

/// `f64::clamp` without its panic on `low > high` (the generic code never passes that).
#[inline(always)]
fn clamp(mut x: f64, low: f64, high: f64) -> f64 {
    if x < low {
        x = low;
    }
    if x > high {
        x = high;
    }
    x
}

/// `L` numbers computed side by side, each lane as [`Real`] for `f64` computes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lanes<const L: usize>(pub [f64; L]);

impl<const L: usize> Lanes<L> {
    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> Self {
        // `from_fn` rather than `array::map`, which is not inlined into the callers' vector code.
        Lanes(std::array::from_fn(|i| f(self.0[i])))
    }

    #[inline(always)]
    fn zip(self, other: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        Lanes(std::array::from_fn(|i| f(self.0[i], other.0[i])))
    }

    #[inline(always)]
    fn compare(self, other: Self, f: impl Fn(f64, f64) -> bool) -> [bool; L] {
        std::array::from_fn(|i| f(self.0[i], other.0[i]))
    }
}

macro_rules! lane_op {
    ($trait:ident, $method:ident, $op:tt) => {
        impl<const L: usize> $trait for Lanes<L> {
            type Output = Self;
            #[inline(always)]
            fn $method(self, other: Self) -> Self {
                self.zip(other, |a, b| a $op b)
            }
        }
    };
}
lane_op!(Add, add, +);
lane_op!(Sub, sub, -);
lane_op!(Mul, mul, *);
lane_op!(Div, div, /);

impl<const L: usize> Neg for Lanes<L> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|a| -a)
    }
}

impl<const L: usize> Real for Lanes<L> {
    type Mask = [bool; L];

    #[inline(always)]
    fn splat(value: f64) -> Self {
        Lanes([value; L])
    }
    #[inline(always)]
    fn lt(self, other: Self) -> [bool; L] {
        self.compare(other, |a, b| a < b)
    }
    #[inline(always)]
    fn ge(self, other: Self) -> [bool; L] {
        self.compare(other, |a, b| a >= b)
    }
    #[inline(always)]
    fn eq(self, other: Self) -> [bool; L] {
        self.compare(other, |a, b| a == b)
    }
    #[inline(always)]
    fn select(when: [bool; L], then: Self, otherwise: Self) -> Self {
        Lanes(std::array::from_fn(|i| {
            if when[i] { then.0[i] } else { otherwise.0[i] }
        }))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        self.map(f64::abs)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        self.map(f64::sqrt)
    }
    #[inline(always)]
    fn clamp(self, low: Self, high: Self) -> Self {
        Lanes(std::array::from_fn(|i| clamp(self.0[i], low.0[i], high.0[i])))
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (sin, cos) = crate::sin_cos_lanes(self.0);
        (Lanes(sin), Lanes(cos))
    }
    #[inline(always)]
    fn tan(self) -> Self {
        Lanes(crate::tan_lanes(self.0))
    }
    #[inline(always)]
    fn atan(self) -> Self {
        Lanes(crate::atan2_lanes(self.0, [1.0; L]))
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        Lanes(crate::atan2_lanes(self.0, x.0))
    }
    #[inline(always)]
    fn hypot(self, other: Self) -> Self {
        Lanes(crate::hypot_lanes(self.0, other.0))
    }
    #[inline(always)]
    fn exp(self) -> Self {
        Lanes(crate::exp_lanes(self.0))
    }
    #[inline(always)]
    fn pow(self, exponent: Self) -> Self {
        Lanes(crate::pow_lanes(self.0, exponent.0))
    }
}
