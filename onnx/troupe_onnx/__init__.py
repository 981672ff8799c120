"""troupe's Python tooling: a PyTorch reference and an ONNX exporter per model family.

One subpackage per family (`armflow`, `umf`), each with its reference (`reference.py`), its
exporter (`export.py`) and its tools; `shared` holds what families have in common (transformer
layers, checkpoint loading, the portable noise generator, the exporter's graph export, bundle
comparison and command line). A family imports `shared`, never another family. Every family
lists its commands in `COMMANDS` (its `__init__.py`), which `onnx/cli.py` runs.
"""
