//! Tensor shapes as a graph declares them (`[batch, 32]`, symbolic dimensions by name) and the
//! layouts cpmx runs: `[batch, size]` with a symbolic or unit batch, or `[size]`.

use std::fmt;

use tract_onnx::prelude::*;

/// One dimension of a declared shape.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Dim {
    /// A fixed size.
    Fixed(usize),
    /// A symbolic size (the batch of an export with a dynamic axis), by its expression.
    Symbol(String),
}

/// A tensor's shape as the graph declares it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TensorShape(pub Vec<Dim>);

/// How agents go through the graph.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Batch {
    /// `[batch, size]` with a symbolic batch: all agents in one run.
    Symbolic,
    /// `[1, size]`: one run per agent.
    One,
    /// `[size]`: one run per agent.
    None,
}

impl TensorShape {
    /// The shape of a typed fact.
    pub fn of(fact: &TypedFact) -> Self {
        TensorShape(
            fact.shape
                .iter()
                .map(|d| match d.to_i64().ok().and_then(|n| usize::try_from(n).ok()) {
                    Some(n) => Dim::Fixed(n),
                    None => Dim::Symbol(d.to_string()),
                })
                .collect(),
        )
    }

    /// The batch and the values per agent, or why this shape is not one cpmx runs.
    pub fn layout(&self) -> Result<(Batch, usize), String> {
        match &self.0[..] {
            [Dim::Fixed(n)] => Ok((Batch::None, *n)),
            [Dim::Symbol(_), Dim::Fixed(n)] => Ok((Batch::Symbolic, *n)),
            [Dim::Fixed(1), Dim::Fixed(n)] => Ok((Batch::One, *n)),
            [Dim::Fixed(b), Dim::Fixed(_)] => Err(format!(
                "its batch is fixed at {b}; export with a dynamic batch axis (torch.onnx.export(..., dynamic_axes={{...: {{0: \"batch\"}}}})) or a batch of 1"
            )),
            [_, Dim::Symbol(s)] | [Dim::Symbol(s)] => Err(format!(
                "its size per agent `{s}` is not fixed; export with a fixed size per agent"
            )),
            _ => Err(format!(
                "cpmx runs [batch, size] or [size] (rank 1 or 2), this has rank {}",
                self.0.len()
            )),
        }
    }
}

impl fmt::Display for TensorShape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("[")?;
        for (i, d) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            match d {
                Dim::Fixed(n) => write!(f, "{n}")?,
                Dim::Symbol(s) => f.write_str(s)?,
            }
        }
        f.write_str("]")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts() {
        let s = |d: Vec<Dim>| TensorShape(d);
        let batch = || Dim::Symbol("batch".into());
        assert_eq!(
            s(vec![batch(), Dim::Fixed(32)]).layout(),
            Ok((Batch::Symbolic, 32))
        );
        assert_eq!(
            s(vec![Dim::Fixed(1), Dim::Fixed(4)]).layout(),
            Ok((Batch::One, 4))
        );
        assert_eq!(s(vec![Dim::Fixed(32)]).layout(), Ok((Batch::None, 32)));
        let fixed = s(vec![Dim::Fixed(8), Dim::Fixed(32)]).layout().unwrap_err();
        assert!(fixed.contains("fixed at 8"), "{fixed}");
        let rank = s(vec![batch(), Dim::Fixed(1), Dim::Fixed(32)])
            .layout()
            .unwrap_err();
        assert!(rank.contains("rank 3"), "{rank}");
        assert_eq!(s(vec![batch(), Dim::Fixed(32)]).to_string(), "[batch, 32]");
    }
}
