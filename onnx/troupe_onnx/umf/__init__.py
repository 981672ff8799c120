"""UMF (text to a group): the PyTorch reference, the exporter and the released-size parity check."""

# `onnx/cli.py umf COMMAND`: COMMAND -> (module of this package, what it does).
COMMANDS = {
    "export": ("export", "write a bundle, or --check one against a fresh export"),
    "official-parity": ("official_parity", "troupe against the reference at the released sizes"),
}
