"""ARMFlow (online reaction): the PyTorch reference, the exporter and the stream-mode study."""

# `onnx/cli.py armflow COMMAND`: COMMAND -> (module of this package, what it does).
COMMANDS = {
    "export": ("export", "write a bundle, or --check one against a fresh export"),
    "stream-deviation": ("stream_deviation", "stream mode against the official clip loop, by VAE window"),
}
