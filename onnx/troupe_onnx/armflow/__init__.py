"""ARMFlow (online reaction): the PyTorch reference, the exporter and the stream-mode study."""

# `onnx/cli.py armflow COMMAND`: COMMAND -> (module of this package, what it does).
COMMANDS = {
    "export": ("export", "write a bundle, or --check one against a fresh export"),
    "quantize": ("quantize", "a copy of a bundle with int8 weights in its matrix products"),
    "stream-deviation": ("stream_deviation", "stream mode against the official clip loop, by VAE window"),
}
