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
//!
//! The same wrapper relabels a contiguous tensor itself when the op only adds, removes or
//! regroups axes whose sizes the plan knows: tract's own evaluation re-derives a reshape's sizes
//! from their symbolic form on every call, and with about a hundred axis ops a token that was
//! 7.5 % of the float16 demo's step (`docs/PERFORMANCE.md`, round four, part nine).

use tract_onnx::prelude::*;
use tract_onnx::tract_core::internal::*;
use tract_onnx::tract_core::ops::change_axes::AxisOp;

/// An axis op whose outputs get natural strides on their length-1 axes.
#[derive(Debug, Clone, PartialEq, Eq)]
struct NaturalUnitAxes {
    op: AxisOp,
    /// How the op relabels a contiguous tensor's shape, where that needs no symbol's value.
    relabel: Option<Relabel>,
}

/// A shape change that moves no value: what an [`AxisOp`] does to a contiguous tensor.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Relabel {
    /// An axis of length 1 inserted at this position.
    Add(usize),
    /// The axis at this position, of length 1, removed.
    Remove(usize),
    /// The axes from `at` with these sizes regrouped into axes of those sizes.
    Regroup {
        at: usize,
        from: TVec<usize>,
        to: TVec<usize>,
    },
}

impl Relabel {
    /// The relabelling `op` makes, when it moves no value and its sizes are all known.
    fn of(op: &AxisOp) -> Option<Self> {
        let known = |dims: &TVec<TDim>| -> Option<TVec<usize>> {
            dims.iter().map(|d| d.to_usize().ok()).collect()
        };
        match op {
            AxisOp::Add(at) => Some(Self::Add(*at)),
            AxisOp::Rm(at) => Some(Self::Remove(*at)),
            AxisOp::Reshape(at, from, to) => {
                let (from, to) = (known(from)?, known(to)?);
                (from.iter().product::<usize>() == to.iter().product::<usize>())
                    .then_some(Self::Regroup { at: *at, from, to })
            }
            AxisOp::Move(..) => None,
        }
    }

    /// The shape a tensor of `shape` takes, or `None` where the op does not apply to it (tract's
    /// own evaluation then reports why).
    fn shape(&self, shape: &[usize]) -> Option<TVec<usize>> {
        // The op replaces the axes `at..` of sizes `replaced` by axes of sizes `inserted`.
        let (at, replaced, inserted): (usize, &[usize], &[usize]) = match self {
            Self::Add(at) => (*at, &[], &[1]),
            Self::Remove(at) => (*at, &[1], &[]),
            Self::Regroup { at, from, to } => (*at, from, to),
        };
        let end = at + replaced.len();
        (shape.get(at..end)? == replaced).then(|| {
            let (before, after) = (&shape[..at], &shape[end..]);
            before
                .iter()
                .chain(inserted)
                .chain(after)
                .copied()
                .collect()
        })
    }
}

impl Op for NaturalUnitAxes {
    fn name(&self) -> StaticName {
        self.op.name()
    }

    fn info(&self) -> TractResult<Vec<String>> {
        self.op.info()
    }

    op_as_typed_op!();
}

impl EvalOp for NaturalUnitAxes {
    op_out_of_plan!();

    fn eval(&self, ctx: &EvalContext, inputs: TVec<TValue>) -> TractResult<TVec<TValue>> {
        if let (Some(relabel), [input]) = (&self.relabel, &inputs[..]) {
            if let Some(shape) = relabel.shape(input.shape()).filter(|_| contiguous(input)) {
                let mut inputs = inputs;
                // Copies only if another operation still holds the value, as tract's would.
                let mut tensor = inputs.remove(0).into_tensor();
                // SAFETY: the values lie row-major (`contiguous`) and `shape` holds as many.
                unsafe { tensor.set_geometry_unchecked(&shape, &Tensor::natural_strides(&shape)) };
                return Ok(tvec!(tensor.into_tvalue()));
            }
        }
        Ok(self
            .op
            .eval(ctx, inputs)?
            .into_iter()
            .map(natural_unit_strides)
            .collect())
    }
}

impl TypedOp for NaturalUnitAxes {
    fn output_facts(&self, inputs: &[&TypedFact]) -> TractResult<TVec<TypedFact>> {
        self.op.output_facts(inputs)
    }

    as_op!();
}

/// Whether `value`'s values lie row-major in plain memory: its strides are the natural ones on
/// every axis longer than 1 (a length-1 axis's stride addresses nothing).
fn contiguous(value: &Tensor) -> bool {
    let natural = Tensor::natural_strides(value.shape());
    value.is_plain_ram()
        && value
            .shape()
            .iter()
            .zip(value.strides().iter().zip(&natural))
            .all(|(&len, (stride, want))| len == 1 || stride == want)
        && value.len() == value.shape().iter().product::<usize>()
}

/// `value` with the strides of its length-1 axes set to their natural value, when only those
/// differ from the natural strides (otherwise as it is).
fn natural_unit_strides(value: TValue) -> TValue {
    let natural = Tensor::natural_strides(value.shape());
    if value.strides() == &*natural || !contiguous(&value) {
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
/// length-1 axes, and contiguous inputs are relabelled without tract's symbolic sizes (the
/// module's comment says why).
pub(crate) fn natural_unit_axes(model: &mut TypedModel) {
    for node in model.nodes_mut() {
        if let Some(axis) = node.op.downcast_ref::<AxisOp>() {
            node.op = Box::new(NaturalUnitAxes {
                op: axis.clone(),
                relabel: Relabel::of(axis),
            });
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

    /// `op` on `input` in a one-op plan whose input has `fact`, with troupe's wrapper or
    /// tract's op alone.
    fn run(op: AxisOp, fact: TypedFact, input: Tensor, wrapped: bool) -> Tensor {
        let mut model = TypedModel::default();
        let x = model.add_source("x", fact).unwrap();
        let y = model.wire_node("op", op, &[x]).unwrap();
        model.select_output_outlets(&y).unwrap();
        if wrapped {
            natural_unit_axes(&mut model);
        }
        let plan = model.into_runnable().unwrap();
        plan.run(tvec!(input.into_tvalue()))
            .unwrap()
            .remove(0)
            .into_tensor()
    }

    #[test]
    fn relabelled_axis_ops_give_what_tracts_own_give() {
        let symbols = SymbolScope::default();
        let b = symbols.sym("B");
        let values: Vec<f32> = (0..12).map(|i| i as f32).collect();
        let input = Tensor::from_shape(&[2, 6], &values).unwrap();
        let cases = [
            // The sizes regrouped are known: relabelled by troupe.
            (
                AxisOp::Reshape(1, tvec![6.into()], tvec![2.into(), 3.into()]),
                true,
            ),
            (AxisOp::Add(1), true),
            (AxisOp::Add(2), true),
            // A size with the row count in it: left to tract.
            (
                AxisOp::Reshape(0, tvec![b.to_dim(), 6.into()], tvec![b.to_dim() * 6]),
                false,
            ),
            // Values moved: left to tract.
            (AxisOp::Move(0, 1), false),
        ];
        for (op, relabelled) in cases {
            assert_eq!(Relabel::of(&op).is_some(), relabelled, "{op:?}");
            let fact = f32::fact(dims![b, 6]);
            let ours = run(op.clone(), fact.clone(), input.clone(), true);
            let tracts = run(op.clone(), fact, input.clone(), false);
            assert_eq!(ours.shape(), tracts.shape(), "{op:?}");
            assert_eq!(
                ours.strides(),
                &*Tensor::natural_strides(ours.shape()),
                "{op:?}"
            );
            assert_eq!(
                ours.to_plain_array_view::<f32>().unwrap(),
                tracts.to_plain_array_view::<f32>().unwrap(),
                "{op:?}"
            );
        }
        // An axis of length 1 removed; a shape that does not fit the op is declined, and tract's
        // own evaluation then reports the error.
        let row = Tensor::from_shape(&[1, 6], &values[..6]).unwrap();
        let removed = run(AxisOp::Rm(0), f32::fact([1, 6]), row, true);
        assert_eq!(removed.shape(), &[6]);
        assert_eq!(Relabel::Remove(0).shape(&[2, 6]), None);
        assert_eq!(
            Relabel::of(&AxisOp::Reshape(
                1,
                tvec![6.into()],
                tvec![2.into(), 3.into()]
            ))
            .unwrap()
            .shape(&[2, 4]),
            None,
            "sizes other than the op's are left to tract"
        );
    }

    #[test]
    fn a_tensor_not_row_major_is_left_to_tract() {
        let mut view = Tensor::from_shape(&[2, 3], &[0f32, 1., 2., 3., 4., 5.]).unwrap();
        unsafe { view.set_geometry_unchecked(&[3, 2], &[1, 3]) };
        assert!(!contiguous(&view));
        let natural = Tensor::from_shape(&[3, 2], &[0f32, 1., 2., 3., 4., 5.]).unwrap();
        assert!(contiguous(&natural));
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
