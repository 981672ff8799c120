//! Natural strides for the axes of length 1 that a plan inserts at run time.
//!
//! A graph planned for any row count (`B`, `N` symbolic) and run with one row makes its batch
//! axis at run time: tract's axis ops insert an axis of length 1 with the stride of the axis
//! after it (`Tensor::insert_axis`), so a `[16, 512]` product reshaped to `[N, 16, 512]` comes
//! out with strides `[512, 512, 1]`, not `[8192, 512, 1]`. tract's element-wise ops take their
//! vectorised path only for tensors whose strides are exactly the natural ones, and the in-place
//! ones hand the same strides on, so every element-wise op after such a reshape ran one element
//! at a time: MAGNet's decoder-gradient graph at one person took 16.5 ms against 11.9 ms planned
//! for one row (`docs/PERFORMANCE.md`, round four). A stride of a length-1 axis never addresses
//! memory, so after each axis op of a plan troupe gives those strides their natural value; the
//! data, the shape and every other stride stay as they are.

use tract_onnx::prelude::*;
use tract_onnx::tract_core::internal::*;
use tract_onnx::tract_core::ops::change_axes::AxisOp;

/// An axis op whose outputs get natural strides on their length-1 axes.
#[derive(Debug, Clone, PartialEq, Eq)]
struct NaturalUnitAxes(AxisOp);

impl Op for NaturalUnitAxes {
    fn name(&self) -> StaticName {
        self.0.name()
    }

    fn info(&self) -> TractResult<Vec<String>> {
        self.0.info()
    }

    op_as_typed_op!();
}

impl EvalOp for NaturalUnitAxes {
    op_out_of_plan!();

    fn eval(&self, ctx: &EvalContext, inputs: TVec<TValue>) -> TractResult<TVec<TValue>> {
        Ok(self
            .0
            .eval(ctx, inputs)?
            .into_iter()
            .map(natural_unit_strides)
            .collect())
    }
}

impl TypedOp for NaturalUnitAxes {
    fn output_facts(&self, inputs: &[&TypedFact]) -> TractResult<TVec<TypedFact>> {
        self.0.output_facts(inputs)
    }

    as_op!();
}

/// `value` with the strides of its length-1 axes set to their natural value, when only those
/// differ from the natural strides (otherwise as it is).
fn natural_unit_strides(value: TValue) -> TValue {
    let natural = Tensor::natural_strides(value.shape());
    if value.strides() == &*natural {
        return value;
    }
    let only_unit_axes = value
        .shape()
        .iter()
        .zip(value.strides().iter().zip(&natural))
        .all(|(&len, (stride, want))| len == 1 || stride == want);
    if !only_unit_axes || value.len() != value.shape().iter().product::<usize>() {
        return value;
    }
    let shape: TVec<usize> = value.shape().into();
    // The axis op made this tensor for its output: taking it copies nothing.
    let mut tensor = value.into_tensor();
    // SAFETY: the shape and the length are unchanged, and the strides differ only on axes of
    // length 1, whose stride no index ever multiplies by anything but 0.
    unsafe { tensor.set_geometry_unchecked(&shape, &natural) };
    tensor.into_tvalue()
}

/// Wraps every axis op of an optimised model so that its outputs have natural strides on their
/// length-1 axes (the module's comment says why).
pub(crate) fn natural_unit_axes(model: &mut TypedModel) {
    for node in model.nodes_mut() {
        if let Some(axis) = node.op.downcast_ref::<AxisOp>() {
            node.op = Box::new(NaturalUnitAxes(axis.clone()));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_inserted_unit_axis_gets_its_natural_stride() {
        let mut t = Tensor::from_shape(&[16, 4], &[1f32; 64]).unwrap();
        t.insert_axis(0).unwrap();
        assert_eq!(t.strides(), &[4, 4, 1]); // tract's own, not the natural [64, 4, 1]
        let fixed = natural_unit_strides(t.clone().into_tvalue());
        assert_eq!(fixed.strides(), &[64, 4, 1]);
        assert_eq!(fixed.shape(), t.shape());
        let floats = |t: &Tensor| {
            t.try_as_plain_ram()
                .unwrap()
                .as_slice::<f32>()
                .unwrap()
                .to_vec()
        };
        assert_eq!(floats(&fixed), floats(&t));
    }

    #[test]
    fn other_tensors_are_left_as_they_are() {
        let natural = Tensor::from_shape(&[2, 3], &[0f32, 1., 2., 3., 4., 5.]).unwrap();
        let same = natural_unit_strides(natural.clone().into_tvalue());
        assert_eq!(same.strides(), natural.strides());
        // Strides that differ on an axis longer than 1 (a view) are not touched.
        let mut view = natural.clone();
        unsafe { view.set_geometry_unchecked(&[3, 2], &[1, 3]) };
        let kept = natural_unit_strides(view.into_tvalue());
        assert_eq!(kept.strides(), &[1, 3]);
    }
}
