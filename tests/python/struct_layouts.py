"""How ctypes lays out the Python binding's structs, for tests/binding_coverage.rs to compare
with the C compiler's layout of include/troupe.h.

    python3 tests/python/struct_layouts.py bindings/python/troupe/_native.py

loads the raw layer alone (it needs no library to be defined) and prints, for each
`ctypes.Structure` it defines, `M <class> <C struct>` (from its docstring's "Mirror of
`troupe_...`"; `<C struct>` is `?` when it names none), `S <class> <size>`, and one
`F <class> <field> <offset> <size>` per leaf field (a nested struct's fields flattened, an array
one field), in bytes.
"""

import ctypes
import importlib.util
import re
import sys


def leaves(cls, start):
    for field in cls._fields_:
        name, kind = field[0], field[1]
        offset = start + getattr(cls, name).offset
        if isinstance(kind, type) and issubclass(kind, ctypes.Structure):
            yield from leaves(kind, offset)
        else:
            yield name, offset, ctypes.sizeof(kind)


def main(path):
    spec = importlib.util.spec_from_file_location("troupe_raw_layer", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for cls in vars(module).values():
        if not (isinstance(cls, type) and issubclass(cls, ctypes.Structure)):
            continue
        if cls.__module__ != module.__name__ or "_fields_" not in vars(cls):
            continue  # ctypes' own, or a base without fields
        mirror = re.search(r"Mirror of `(troupe_\w+)`", cls.__doc__ or "")
        print("M", cls.__name__, mirror.group(1) if mirror else "?")
        print("S", cls.__name__, ctypes.sizeof(cls))
        for name, offset, size in leaves(cls, 0):
            print("F", cls.__name__, name, offset, size)


if __name__ == "__main__":
    main(sys.argv[1])
