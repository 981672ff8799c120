//! Checks on an ONNX model's protobuf before tract builds anything from it.
//!
//! tract trusts the sizes a graph declares: a tensor whose dims claim 2^40 elements, or a
//! `ConstantOfShape` fed a constant shape of that size, is allocated while the model is typed
//! or optimised, and a failed allocation aborts the process. So the sizes a graph states
//! directly are bounded here first: the operator set, the node count, every initializer and
//! constant (its declared element count must be what it stores), every declared value shape, and
//! the outputs of the operators that build a tensor from constant numbers (`ConstantOfShape`,
//! `Expand`, `Tile`, `Range`). Sizes that only arise from a longer chain of constant folding are
//! not bounded here; tract turning one into a panic is caught by the loader.

use std::collections::HashMap;

use tract_onnx::pb::{self, tensor_proto::DataType};

use crate::shared::graph_spec::Weights;
use crate::shared::limits::LIMITS;

/// The ONNX operator sets (default domain) this runtime accepts: the range tract supports.
pub(crate) const OPSETS: std::ops::RangeInclusive<i64> = 9..=21;

type Check = std::result::Result<(), String>;

/// Checks `model` before it is handed to tract (see the module documentation).
pub(crate) fn check_model(model: &pb::ModelProto) -> Check {
    for import in &model.opset_import {
        let domain = import.domain.as_str();
        if domain.is_empty() || domain == "ai.onnx" {
            if !OPSETS.contains(&import.version) {
                return Err(format!(
                    "declares ONNX operator set {}; this runtime reads {} to {}",
                    import.version,
                    OPSETS.start(),
                    OPSETS.end()
                ));
            }
        } else if domain != "ai.onnx.ml" {
            return Err(format!(
                "uses the operator domain `{domain}`, which troupe does not run"
            ));
        }
    }
    if !model.functions.is_empty() || !model.training_info.is_empty() {
        return Err(
            "holds functions or training information, which a bundle graph never has".into(),
        );
    }
    let graph = model.graph.as_ref().ok_or("holds no graph")?;
    let mut nodes = 0u64;
    check_graph(graph, &mut nodes)
}

/// Checks that the graph's matrix products hold the weights the manifest declares: int8 graphs
/// have integer products (`MatMulInteger`, `ConvInteger`) and float16 graphs float16
/// initializers; a graph declared otherwise has neither.
pub(crate) fn check_weights(model: &pb::ModelProto, declared: Weights) -> Check {
    const INTEGER: [&str; 2] = ["MatMulInteger", "ConvInteger"];
    const FLOAT16: i32 = 10; // TensorProto.DataType.FLOAT16
    let graph = model.graph.as_ref();
    let integer = graph.map_or(0, |g| {
        g.node
            .iter()
            .filter(|n| INTEGER.contains(&n.op_type.as_str()))
            .count()
    });
    let half = graph.map_or(0, |g| {
        g.initializer
            .iter()
            .filter(|t| t.data_type == FLOAT16)
            .count()
    });
    match (declared, integer, half) {
        (Weights::Int8, 0, _) => Err(
            "is declared with int8 weights (`\"weights\": \"int8\"`) but has no integer matrix \
             product"
                .into(),
        ),
        (Weights::Float16, _, 0) => Err(
            "is declared with float16 weights (`\"weights\": \"float16\"`) but holds no float16 \
             initializer"
                .into(),
        ),
        (Weights::Float32 | Weights::Float16, n, _) if n > 0 => Err(format!(
            "has {n} integer matrix products but is declared with {} weights; a bundle \
             with reduced precision must say so (`\"weights\": \"int8\"` on the graph)",
            declared.name()
        )),
        (Weights::Float32 | Weights::Int8, _, n) if n > 0 => Err(format!(
            "holds {n} float16 initializers but is declared with {} weights; a bundle with \
             reduced precision must say so (`\"weights\": \"float16\"` on the graph)",
            declared.name()
        )),
        _ => Ok(()),
    }
}

fn check_graph(graph: &pb::GraphProto, nodes: &mut u64) -> Check {
    *nodes += graph.node.len() as u64;
    if *nodes > LIMITS.max_graph_nodes {
        return Err(format!(
            "has more than troupe's limit of {} nodes",
            LIMITS.max_graph_nodes
        ));
    }
    if !graph.sparse_initializer.is_empty() {
        return Err("holds sparse initializers, which troupe does not read".into());
    }
    let mut constants: HashMap<&str, Vec<i64>> = HashMap::new();
    for tensor in &graph.initializer {
        check_tensor(tensor, &format!("initializer `{}`", tensor.name))?;
        if let Some(values) = small_ints(tensor) {
            constants.insert(tensor.name.as_str(), values);
        }
    }
    for info in graph
        .input
        .iter()
        .chain(&graph.output)
        .chain(&graph.value_info)
    {
        check_value_info(info)?;
    }
    for node in &graph.node {
        let what = || format!("node `{}` ({})", node.name, node.op_type);
        for attribute in &node.attribute {
            let tensors = attribute.t.iter().chain(&attribute.tensors);
            for tensor in tensors {
                check_tensor(
                    tensor,
                    &format!("{}, attribute `{}`", what(), attribute.name),
                )?;
            }
            if attribute.sparse_tensor.is_some() || !attribute.sparse_tensors.is_empty() {
                return Err(format!("{} holds a sparse tensor", what()));
            }
            for sub in attribute.g.iter().chain(&attribute.graphs) {
                check_graph(sub, nodes)?;
            }
        }
        if node.op_type == "Constant" {
            let value = node.attribute.iter().find(|a| a.name == "value");
            if let (Some(tensor), Some(out)) =
                (value.and_then(|a| a.t.as_ref()), node.output.first())
            {
                if let Some(values) = small_ints(tensor) {
                    constants.insert(out.as_str(), values);
                }
            }
        }
        let constant = |i: usize| node.input.get(i).and_then(|n| constants.get(n.as_str()));
        let built = match node.op_type.as_str() {
            "ConstantOfShape" | "Expand" => {
                constant(usize::from(node.op_type == "Expand")).map(|shape| elements(shape))
            }
            "Tile" => constant(1).map(|repeats| elements(repeats)),
            "Range" => match (constant(0), constant(1), constant(2)) {
                (Some(start), Some(limit), Some(delta)) => Some(range_len(start, limit, delta)),
                _ => None,
            },
            _ => None,
        };
        if let Some(count) = built {
            let count =
                count.ok_or_else(|| format!("{} builds a tensor of invalid size", what()))?;
            if count > LIMITS.max_tensor_elements {
                return Err(format!(
                    "{} builds a tensor of {count} elements, above troupe's limit of {}",
                    what(),
                    LIMITS.max_tensor_elements
                ));
            }
        }
    }
    Ok(())
}

/// The element count of a shape, `None` when a dimension is negative or the product overflows.
fn elements(dims: &[i64]) -> Option<u64> {
    dims.iter().try_fold(1u64, |acc, &d| {
        u64::try_from(d).ok().and_then(|d| acc.checked_mul(d))
    })
}

/// The length of `Range(start, limit, delta)` on scalars, `None` when delta is 0.
fn range_len(start: &[i64], limit: &[i64], delta: &[i64]) -> Option<u64> {
    let (&[s], &[l], &[d]) = (start, limit, delta) else {
        return None;
    };
    if d == 0 {
        return None;
    }
    let span = (i128::from(l) - i128::from(s)) / i128::from(d);
    u64::try_from(span.max(0)).ok()
}

/// Bytes per element of the data types a graph may store raw, `None` for others.
fn element_bytes(data_type: i32) -> Option<u64> {
    use DataType::*;
    Some(match DataType::try_from(data_type).ok()? {
        Uint8 | Int8 | Bool | Float8e4m3fn | Float8e4m3fnuz | Float8e5m2 | Float8e5m2fnuz => 1,
        Uint16 | Int16 | Float16 | Bfloat16 => 2,
        Float | Int32 | Uint32 => 4,
        Double | Int64 | Uint64 | Complex64 => 8,
        Complex128 => 16,
        _ => return None,
    })
}

/// A stored tensor: dimensions non-negative, at most `LIMITS.max_tensor_elements` elements, all
/// of them present in the file (no external data).
fn check_tensor(tensor: &pb::TensorProto, what: &str) -> Check {
    if !tensor.external_data.is_empty()
        || tensor.data_location == Some(1)
        || tensor.segment.is_some()
    {
        return Err(format!("{what} refers to data outside the graph file"));
    }
    let count = elements(&tensor.dims)
        .filter(|&c| c <= LIMITS.max_tensor_elements)
        .ok_or_else(|| {
            format!(
                "{what} declares dims {:?}, more than troupe's limit of {} elements",
                tensor.dims, LIMITS.max_tensor_elements
            )
        })?;
    let stored = if !tensor.raw_data.is_empty() {
        let size = element_bytes(tensor.data_type)
            .ok_or_else(|| format!("{what} stores raw data of type {}", tensor.data_type))?;
        tensor.raw_data.len() as u64 / size
    } else {
        [
            tensor.float_data.len(),
            tensor.int32_data.len(),
            tensor.int64_data.len(),
            tensor.double_data.len(),
            tensor.uint64_data.len(),
            tensor.string_data.len(),
        ]
        .into_iter()
        .max()
        .unwrap_or(0) as u64
    };
    if stored < count {
        return Err(format!(
            "{what} declares {count} elements but stores {stored}"
        ));
    }
    Ok(())
}

/// The values of a small integer tensor (shapes, repeats, range bounds), if it is one.
fn small_ints(tensor: &pb::TensorProto) -> Option<Vec<i64>> {
    let count = elements(&tensor.dims)?;
    if count > 16 {
        return None;
    }
    let ty = DataType::try_from(tensor.data_type).ok()?;
    let values: Vec<i64> = match ty {
        DataType::Int64 if !tensor.raw_data.is_empty() => tensor
            .raw_data
            .chunks_exact(8)
            .map(|b| i64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect(),
        DataType::Int32 if !tensor.raw_data.is_empty() => tensor
            .raw_data
            .chunks_exact(4)
            .map(|b| i64::from(i32::from_le_bytes(b.try_into().expect("4 bytes"))))
            .collect(),
        DataType::Int64 => tensor.int64_data.clone(),
        DataType::Int32 => tensor.int32_data.iter().map(|&v| i64::from(v)).collect(),
        _ => return None,
    };
    (values.len() as u64 == count).then_some(values)
}

/// A declared value (input, output, intermediate): fixed dimensions non-negative, and at most
/// `LIMITS.max_tensor_elements` elements when all are fixed.
fn check_value_info(info: &pb::ValueInfoProto) -> Check {
    use pb::tensor_shape_proto::dimension::Value;
    let Some(pb::type_proto::Value::TensorType(tensor)) =
        info.r#type.as_ref().and_then(|t| t.value.as_ref())
    else {
        return Ok(());
    };
    let Some(shape) = &tensor.shape else {
        return Ok(());
    };
    let fixed: Vec<i64> = shape
        .dim
        .iter()
        .filter_map(|d| match d.value {
            Some(Value::DimValue(v)) => Some(v),
            _ => None,
        })
        .collect();
    match elements(&fixed) {
        Some(count) if count <= LIMITS.max_tensor_elements => Ok(()),
        _ => Err(format!(
            "value `{}` is declared with dims {fixed:?}, more than troupe's limit of {} elements",
            info.name, LIMITS.max_tensor_elements
        )),
    }
}
