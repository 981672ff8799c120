//! The interface of one ONNX graph as a manifest declares it (file, tensors, element types,
//! shapes) and the helpers families use to state the interface they require of their graphs.
//! Family-neutral: each family's manifest section lists its graphs with these types, and
//! [`check_contract`] compares the declared interface with the required one.

use std::fmt;

use serde::{Deserialize, Serialize};

/// One ONNX graph and its interface.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct GraphSpec {
    /// File name, relative to the bundle directory.
    pub file: String,
    /// Inputs, by name.
    pub inputs: Vec<TensorSpec>,
    /// Outputs, by name.
    pub outputs: Vec<TensorSpec>,
    /// How the graph stores the weights of its matrix products (float32 when absent). Checked
    /// against the file at load, so a bundle cannot reduce precision silently.
    #[serde(default, skip_serializing_if = "Weights::is_float32")]
    pub weights: Weights,
}

/// The storage of a graph's matrix-product weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Weights {
    /// 32-bit floats, as trained.
    #[default]
    Float32,
    /// 8-bit integers with float scales (`MatMulInteger`), activations quantized per tensor at
    /// run time (`DynamicQuantizeLinear`): `onnx/cli.py armflow quantize`. Smaller and faster;
    /// outputs differ from float32 by the quantization error, and a session's output in a batch
    /// depends on its batch mates within that error (one activation scale per batch).
    Int8,
    /// 16-bit floats (`float16` initializers, each cast to float32 where a matrix product uses
    /// it): `onnx/cli.py armflow quantize --weights float16`. troupe keeps them in 16 bits and
    /// multiplies them with float32 activations (tract's mixed kernels), so a batch-1 step reads
    /// half the bytes; outputs differ from float32 by the weights' rounding alone, and a batched
    /// session's output equals its output alone.
    Float16,
}

impl Weights {
    /// Whether this is the float32 default.
    pub fn is_float32(&self) -> bool {
        *self == Weights::Float32
    }

    /// The manifest's name for it.
    pub fn name(&self) -> &'static str {
        match self {
            Weights::Float32 => "float32",
            Weights::Int8 => "int8",
            Weights::Float16 => "float16",
        }
    }
}

/// Element type of a graph tensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DType {
    /// 32-bit float.
    Float32,
    /// 64-bit signed integer.
    Int64,
}

/// One dimension: a fixed size or a symbol (`T`, `P`, `P+S`, ...) resolved per call.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Dim {
    /// A size fixed by the bundle.
    Fixed(usize),
    /// A size that varies from call to call.
    Symbol(String),
}

/// Name, element type and shape of one graph input or output.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TensorSpec {
    /// Tensor name in the ONNX graph.
    pub name: String,
    /// Element type.
    pub dtype: DType,
    /// Shape.
    pub shape: Vec<Dim>,
}

impl fmt::Display for Dim {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Dim::Fixed(n) => write!(f, "{n}"),
            Dim::Symbol(s) => write!(f, "{s}"),
        }
    }
}

impl fmt::Display for TensorSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let dims: Vec<String> = self.shape.iter().map(Dim::to_string).collect();
        let dtype = match self.dtype {
            DType::Float32 => "float32",
            DType::Int64 => "int64",
        };
        write!(f, "`{}` {dtype} [{}]", self.name, dims.join(", "))
    }
}

/// Shorthands for writing graph contracts.
pub(crate) fn float(name: &str, shape: Vec<Dim>) -> TensorSpec {
    TensorSpec {
        name: name.into(),
        dtype: DType::Float32,
        shape,
    }
}

/// A symbolic dimension.
pub(crate) fn sym(name: &str) -> Dim {
    Dim::Symbol(name.into())
}

/// The declared graph's file with the required interface.
pub(crate) fn contract(
    g: &GraphSpec,
    inputs: Vec<TensorSpec>,
    outputs: Vec<TensorSpec>,
) -> GraphSpec {
    GraphSpec {
        file: g.file.clone(),
        inputs,
        outputs,
        weights: g.weights,
    }
}

/// Checks one declared graph against the interface the runtime requires of it (`role` and the
/// file name it in the message: a role may hold several graphs).
pub(crate) fn check_contract(
    role: &str,
    declared: &GraphSpec,
    expected: &GraphSpec,
) -> std::result::Result<(), String> {
    for (kind, got, want) in [
        ("inputs", &declared.inputs, &expected.inputs),
        ("outputs", &declared.outputs, &expected.outputs),
    ] {
        compare_tensor_lists(got, want)
            .map_err(|e| format!("graphs.{role}.{kind} ({}): {e}", declared.file))?;
    }
    Ok(())
}

/// Same names (in any order), dtypes, ranks and fixed dims; symbols may be named freely.
fn compare_tensor_lists(
    got: &[TensorSpec],
    want: &[TensorSpec],
) -> std::result::Result<(), String> {
    for w in want {
        let g = got
            .iter()
            .find(|g| g.name == w.name)
            .ok_or_else(|| format!("missing tensor {w}"))?;
        let same_dims = g.shape.len() == w.shape.len()
            && g.shape.iter().zip(&w.shape).all(|(a, b)| match (a, b) {
                (Dim::Fixed(x), Dim::Fixed(y)) => x == y,
                (Dim::Symbol(_), Dim::Symbol(_)) => true,
                _ => false,
            });
        if g.dtype != w.dtype || !same_dims {
            return Err(format!("tensor declared as {g}, the runtime requires {w}"));
        }
    }
    if let Some(extra) = got.iter().find(|g| !want.iter().any(|w| w.name == g.name)) {
        return Err(format!("unexpected tensor {extra}"));
    }
    Ok(())
}
