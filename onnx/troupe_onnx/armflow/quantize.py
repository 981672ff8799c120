"""`onnx/cli.py armflow quantize`: an ARMFlow bundle with int8 weights in its matrix products
(`shared/quantize.py` does the work and documents the scheme)."""


def main(argv: list[str] | None = None, prog: str | None = None):
    """`onnx/cli.py armflow quantize`."""
    from troupe_onnx.shared.quantize import main as quantize

    quantize(argv, prog)
