"""MAGNet (multi-agent diffusion forcing): the PyTorch reference, the checkpoint reader and the exporter."""

# `onnx/cli.py magnet COMMAND`: COMMAND -> (module of this package, what it does).
COMMANDS = {
    "export": ("export", "write a bundle (random weights or a released checkpoint), or --check one"),
}
