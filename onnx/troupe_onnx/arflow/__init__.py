"""ARFlow (action-to-reaction flow matching with physical guidance): the PyTorch reference, its sampler and the exporter."""

# `onnx/cli.py arflow COMMAND`: COMMAND -> (module of this package, what it does).
COMMANDS = {
    "export": ("export", "write a bundle with random weights (and goldens), or --check one"),
}
