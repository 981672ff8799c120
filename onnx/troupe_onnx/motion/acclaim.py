"""Acclaim ASF/AMC motion capture (the CMU Graphics Lab database's format): a reader and forward
kinematics in numpy.

ASF (skeleton): `:units` (`length` multiplier, `angle deg|rad`), `:root` (`order` of the AMC root
channels, `axis` order and `position` / `orientation` of the root's pre-set offset),
`:bonedata` (`begin` ... `end` blocks: `id`, `name`, `direction`, `length`, `axis a b c ORDER`,
`dof`, `limits`), `:hierarchy` (`begin`, lines `parent child...`, `end`). Other sections
(`:version`, `:name`, `:documentation`, ...) are read or skipped. `#` starts a comment; commas
and parentheses are white space (the format's definition).

AMC (motion): optional `:FULLY-SPECIFIED`, `:DEGREES` / `:RADIANS`, then per frame its number on
a line of its own and one line `bone value...` per bone with degrees of freedom (the root's
values in its `order`).

Forward kinematics, the Acclaim convention:
- an Euler triple with order `XYZ` turns about x first, then y, then z: R = Rz · Ry · Rx (fixed
  axes); the same for a bone's `dof rx ry rz` values in the order listed;
- a bone's axis frame is C = Euler(axis angles, axis order); its motion M = Euler(dof values in
  dof order); its world rotation R = R_parent · C · M · C⁻¹;
- a bone starts at its parent's end (the root's position for children of the root) and ends at
  start + length · R · direction;
- the root's world rotation is R0 · M_root and its position p0 + R0 · t, where M_root and t come
  from the AMC root channels and R0 = Euler(orientation, axis), p0 = position are the ASF's
  pre-set offset of all the motion (zero in CMU files and in every file VICON writes).

Lengths and root translations stay in file units; CMU's convention is that a file unit is
`1 / length` inches (`length 0.45`: metres = value / 0.45 · 0.0254), `Asf.cmu_metres_per_unit`.

Malformed input raises `AcclaimError` naming the file, the line and the bone.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

INCH = 0.0254
ROTATIONS = ("rx", "ry", "rz")
TRANSLATIONS = ("tx", "ty", "tz")


class AcclaimError(ValueError):
    """Malformed ASF or AMC input; the message names the file, the line and the bone."""


@dataclass
class Bone:
    name: str
    line: int  # where its `begin` is
    id: int | None = None
    direction: np.ndarray = field(default_factory=lambda: np.zeros(3))  # unit
    length: float = 0.0  # file units
    axis: np.ndarray = field(default_factory=lambda: np.zeros(3))  # radians
    axis_order: str = "XYZ"
    dof: tuple[str, ...] = ()
    limits: list[tuple[float, float]] = field(default_factory=list)  # in the file's angle unit
    parent: str | None = None
    children: list[str] = field(default_factory=list)


@dataclass
class Asf:
    path: str
    name: str = ""
    version: str = ""
    length_unit: float = 1.0  # the `:units length` multiplier
    angle_unit: str = "deg"
    mass_unit: float = 1.0
    root_order: tuple[str, ...] = ()  # lower case: tx ty tz rx ry rz in AMC order
    root_axis: str = "XYZ"
    root_position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    root_orientation: np.ndarray = field(default_factory=lambda: np.zeros(3))  # radians
    bones: dict[str, Bone] = field(default_factory=dict)  # file order
    root_children: list[str] = field(default_factory=list)

    @property
    def cmu_metres_per_unit(self) -> float:
        """Metres per file unit by the CMU convention: a unit is 1 / length inches."""
        return INCH / self.length_unit

    def order(self) -> list[str]:
        """Bone names, every parent before its children (depth first from the root)."""
        out: list[str] = []
        stack = list(reversed(self.root_children))
        while stack:
            name = stack.pop()
            out.append(name)
            stack.extend(reversed(self.bones[name].children))
        return out


@dataclass
class Amc:
    path: str
    frames: np.ndarray  # [F] frame numbers as the file gives them
    values: dict[str, np.ndarray]  # "root" and every bone with dofs: [F, channels], angles in radians


def _tokens(path: Path) -> list[tuple[int, list[str]]]:
    """(line number, tokens) of every non-empty line, comments dropped, `,()` as white space."""
    out = []
    try:
        text = path.read_text()
    except UnicodeDecodeError as e:
        raise AcclaimError(f"{path}: not a text file ({e})") from None
    table = str.maketrans({",": " ", "(": " ", ")": " "})
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.split("#", 1)[0].translate(table).split()
        if line:
            out.append((number, line))
    return out


def euler(angles: np.ndarray, order: str) -> np.ndarray:
    """Rotation matrices of Euler angles (radians, [..., len(order)]) applied about fixed axes in
    `order` (`"XYZ"`: x first, R = Rz · Ry · Rx)."""
    angles = np.asarray(angles, dtype=np.float64)
    r = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for k, axis in enumerate(order.lower()):
        c, s = np.cos(angles[..., k]), np.sin(angles[..., k])
        t = np.zeros(angles.shape[:-1] + (3, 3))
        i = "xyz".index(axis)
        j, l = (i + 1) % 3, (i + 2) % 3
        t[..., i, i] = 1.0
        t[..., j, j], t[..., j, l] = c, -s
        t[..., l, j], t[..., l, l] = s, c
        r = t @ r
    return r


def read_asf(path: str | Path) -> Asf:
    path = Path(path)
    lines = _tokens(path)
    asf = Asf(path=str(path))

    def fail(line: int, message: str, bone: str | None = None):
        where = f"{path}:{line}" + (f": bone {bone}" if bone else "")
        raise AcclaimError(f"{where}: {message}")

    def numbers(line: int, values: list[str], n: int | None, what: str, bone: str | None = None) -> list[float]:
        if n is not None and len(values) != n:
            fail(line, f"{what} needs {n} number(s), got {len(values)}: {' '.join(values)!r}", bone)
        try:
            return [float(v) for v in values]
        except ValueError:
            fail(line, f"{what}: {' '.join(values)!r} is not numbers", bone)

    def angle(v: list[float]) -> np.ndarray:
        a = np.array(v, dtype=np.float64)
        return np.deg2rad(a) if asf.angle_unit == "deg" else a

    sections: dict[str, list[tuple[int, list[str]]]] = {}
    section_line: dict[str, int] = {}
    current = None
    for number, toks in lines:
        if toks[0].startswith(":"):
            current = toks[0][1:].lower()
            if current in sections:
                fail(number, f"section :{current} appears twice (first at line {section_line[current]})")
            sections[current], section_line[current] = [(number, toks[1:])] if toks[1:] else [], number
        elif current is None:
            fail(number, f"{toks[0]!r} before any :section")
        else:
            sections[current].append((number, toks))
    for required in ("root", "bonedata", "hierarchy"):
        if required not in sections:
            raise AcclaimError(f"{path}: no :{required} section")

    for number, toks in sections.get("version", []):
        asf.version = toks[0]
    for number, toks in sections.get("name", []):
        asf.name = " ".join(toks)
    for number, toks in sections.get("units", []):
        key = toks[0].lower()
        if key == "length":
            (asf.length_unit,) = numbers(number, toks[1:], 1, "units length")
            if not asf.length_unit > 0:
                fail(number, f"units length must be positive, got {asf.length_unit}")
        elif key == "mass":
            (asf.mass_unit,) = numbers(number, toks[1:], 1, "units mass")
        elif key == "angle":
            if len(toks) != 2 or toks[1].lower() not in ("deg", "rad"):
                fail(number, f"units angle must be deg or rad, got {' '.join(toks[1:])!r}")
            asf.angle_unit = toks[1].lower()
        else:
            fail(number, f"unknown unit {toks[0]!r}")

    seen_order = False
    for number, toks in sections["root"]:
        key = toks[0].lower()
        if key == "order":
            order = tuple(t.lower() for t in toks[1:])
            bad = [t for t in order if t not in ROTATIONS + TRANSLATIONS]
            if bad or len(set(order)) != len(order):
                fail(number, f"root order must be distinct channels among TX TY TZ RX RY RZ, got {' '.join(toks[1:])!r}", "root")
            asf.root_order, seen_order = order, True
        elif key == "axis":
            if len(toks) != 2 or sorted(toks[1].lower()) != ["x", "y", "z"]:
                fail(number, f"root axis must be an order of XYZ, got {' '.join(toks[1:])!r}", "root")
            asf.root_axis = toks[1].upper()
        elif key == "position":
            asf.root_position = np.array(numbers(number, toks[1:], 3, "root position", "root"))
        elif key == "orientation":
            asf.root_orientation = angle(numbers(number, toks[1:], 3, "root orientation", "root"))
        else:
            fail(number, f"unknown root field {toks[0]!r}", "root")
    if not seen_order:
        raise AcclaimError(f"{path}:{section_line['root']}: bone root: no `order` line")

    bone: Bone | None = None
    pending_limits = 0  # limit pairs still expected on continuation lines
    for number, toks in sections["bonedata"]:
        key = toks[0].lower()
        label = bone.name if bone and bone.name else None
        if key == "begin":
            if bone is not None:
                fail(number, f"`begin` inside the bone that begins at line {bone.line} (missing `end`)", label)
            bone, pending_limits = Bone(name="", line=number), 0
            continue
        if bone is None:
            fail(number, f"{toks[0]!r} outside a begin ... end block")
        if pending_limits and key not in ("end", "id", "name", "direction", "length", "axis", "dof", "limits", "bodymass", "cofmass"):
            vals = numbers(number, toks, None, "limits", label)
            if len(vals) % 2:
                fail(number, "limits come in (min max) pairs", label)
            for k in range(0, len(vals), 2):
                bone.limits.append((vals[k], vals[k + 1]))
            pending_limits -= len(vals) // 2
            if pending_limits < 0:
                fail(number, f"more limits than the {len(bone.dof)} dof", label)
            continue
        if pending_limits:
            fail(number, f"{pending_limits} limit pair(s) missing for dof {' '.join(bone.dof)}", label)
        if key == "end":
            if not bone.name:
                fail(bone.line, "a bone without a name")
            if bone.name in asf.bones or bone.name == "root":
                fail(bone.line, "the name is used twice", bone.name)
            if bone.length < 0:
                fail(bone.line, f"negative length {bone.length}", bone.name)
            asf.bones[bone.name] = bone
            bone = None
        elif key == "id":
            (value,) = numbers(number, toks[1:], 1, "id", label)
            bone.id = int(value)
        elif key == "name":
            if len(toks) != 2:
                fail(number, f"a name is one word, got {' '.join(toks[1:])!r}", label)
            bone.name = toks[1]
        elif key == "direction":
            d = np.array(numbers(number, toks[1:], 3, "direction", label))
            n = np.linalg.norm(d)
            if not n > 0:
                fail(number, "direction has no length", label)
            bone.direction = d / n
        elif key == "length":
            (bone.length,) = numbers(number, toks[1:], 1, "length", label)
        elif key == "axis":
            if len(toks) != 5 or sorted(toks[4].lower()) != ["x", "y", "z"]:
                fail(number, f"axis needs three angles and an order such as XYZ, got {' '.join(toks[1:])!r}", label)
            bone.axis = angle(numbers(number, toks[1:4], 3, "axis", label))
            bone.axis_order = toks[4].upper()
        elif key == "dof":
            dof = tuple(t.lower() for t in toks[1:])
            unsupported = [t for t in dof if t not in ROTATIONS]
            if unsupported:
                fail(number, f"dof {' '.join(unsupported)} not supported (rx, ry and rz are)", label)
            if not dof or len(set(dof)) != len(dof):
                fail(number, f"dof must list distinct channels, got {' '.join(toks[1:])!r}", label)
            bone.dof = dof
        elif key == "limits":
            if not bone.dof:
                fail(number, "limits before dof", label)
            pending_limits = len(bone.dof)
            vals = numbers(number, toks[1:], None, "limits", label)
            if len(vals) % 2:
                fail(number, "limits come in (min max) pairs", label)
            for k in range(0, len(vals), 2):
                bone.limits.append((vals[k], vals[k + 1]))
            pending_limits -= len(vals) // 2
        elif key in ("bodymass", "cofmass"):
            pass
        else:
            fail(number, f"unknown bone field {toks[0]!r}", label)
    if bone is not None:
        fail(bone.line, "bone without `end`", bone.name or None)
    if not asf.bones:
        raise AcclaimError(f"{path}:{section_line['bonedata']}: no bones")

    inside = False
    for number, toks in sections["hierarchy"]:
        key = toks[0].lower()
        if key == "begin":
            inside = True
            continue
        if key == "end":
            inside = False
            continue
        if not inside:
            fail(number, f"{toks[0]!r} outside the hierarchy's begin ... end")
        parent, children = toks[0], toks[1:]
        if parent != "root" and parent not in asf.bones:
            fail(number, f"unknown bone {parent!r} in the hierarchy", parent)
        for child in children:
            if child not in asf.bones:
                fail(number, f"unknown bone {child!r} in the hierarchy", child)
            b = asf.bones[child]
            if b.parent is not None:
                fail(number, f"a second parent {parent!r} (already a child of {b.parent!r})", child)
            b.parent = parent
            (asf.root_children if parent == "root" else asf.bones[parent].children).append(child)
    order = set()
    stack = list(asf.root_children)
    while stack:  # reachable from the root; every bone has one parent, so no cycles then
        name = stack.pop()
        order.add(name)
        stack.extend(asf.bones[name].children)
    for name, b in asf.bones.items():
        if name not in order:
            what = "has no parent in the hierarchy" if b.parent is None else "is not connected to the root (a cycle)"
            fail(b.line, what, name)
    return asf


def read_amc(path: str | Path, asf: Asf) -> Amc:
    path = Path(path)
    channels = {"root": len(asf.root_order)}
    channels.update({name: len(b.dof) for name, b in asf.bones.items() if b.dof})
    degrees = asf.angle_unit == "deg"
    frames: list[int] = []
    rows: dict[str, list[list[float]]] = {name: [] for name in channels}
    frame_line = 0
    seen: set[str] = set()

    def fail(line: int, message: str, bone: str | None = None):
        where = f"{path}:{line}" + (f": bone {bone}" if bone else "")
        raise AcclaimError(f"{where}: {message}")

    def close_frame():
        missing = [n for n in channels if n not in seen]
        if frames and missing:
            fail(frame_line, f"frame {frames[-1]} has no values for {', '.join(missing)}", missing[0])

    for number, toks in _tokens(path):
        if toks[0].startswith(":"):
            key = toks[0].upper()
            if frames:
                fail(number, f"{toks[0]} after the first frame")
            if key == ":DEGREES":
                degrees = True
            elif key == ":RADIANS":
                degrees = False
            # :FULLY-SPECIFIED and others: nothing to do.
            continue
        if len(toks) == 1 and toks[0].lstrip("-").isdigit():
            close_frame()
            n = int(toks[0])
            if frames and n <= frames[-1]:
                fail(number, f"frame {n} after frame {frames[-1]}")
            frames.append(n)
            frame_line, seen = number, set()
            continue
        name = toks[0]
        if not frames:
            fail(number, f"{name!r} before the first frame number", name)
        if name not in channels:
            known = "a bone without dof" if name in asf.bones else "not a bone of the skeleton"
            fail(number, f"{known}", name)
        if name in seen:
            fail(number, f"given twice in frame {frames[-1]}", name)
        if len(toks) - 1 != channels[name]:
            fail(number, f"{channels[name]} value(s) expected, got {len(toks) - 1}", name)
        try:
            values = [float(v) for v in toks[1:]]
        except ValueError:
            fail(number, f"{' '.join(toks[1:])!r} is not numbers", name)
        if not all(np.isfinite(values)):
            fail(number, "values are not finite", name)
        seen.add(name)
        rows[name].append(values)
    close_frame()
    if not frames:
        raise AcclaimError(f"{path}: no frames")
    scale = np.pi / 180.0 if degrees else 1.0
    values = {}
    for name, data in rows.items():
        v = np.array(data, dtype=np.float64).reshape(len(frames), channels[name])
        if name == "root":
            rot = [k for k, c in enumerate(asf.root_order) if c in ROTATIONS]
            v[:, rot] *= scale
        else:
            v *= scale
        values[name] = v
    return Amc(path=str(path), frames=np.array(frames), values=values)


@dataclass
class Pose:
    """Forward kinematics of every frame, file units."""

    names: list[str]  # bones, parents first
    root: np.ndarray  # [F, 3] root positions
    starts: np.ndarray  # [F, B, 3] where each bone starts (its parent's end)
    ends: np.ndarray  # [F, B, 3] where each bone ends
    rotations: np.ndarray  # [F, B, 3, 3] world rotations

    def end(self, bone: str) -> np.ndarray:
        return self.ends[:, self.names.index(bone)]

    def start(self, bone: str) -> np.ndarray:
        return self.starts[:, self.names.index(bone)]


def forward_kinematics(asf: Asf, amc: Amc, frames: slice | np.ndarray | None = None) -> Pose:
    """Bone ends of the AMC's frames (all, or the selected rows), file units."""
    sel = slice(None) if frames is None else frames
    root_values = amc.values["root"][sel]
    n = len(root_values)
    rot = [c for c in asf.root_order if c in ROTATIONS]
    angles = np.stack([root_values[:, asf.root_order.index(c)] for c in rot], axis=-1) if rot else np.zeros((n, 0))
    t = np.zeros((n, 3))
    for k, c in enumerate(TRANSLATIONS):
        if c in asf.root_order:
            t[:, k] = root_values[:, asf.root_order.index(c)]
    pre = euler(asf.root_orientation, asf.root_axis)
    root_rotation = pre @ euler(angles, "".join(c[1] for c in rot))
    root = asf.root_position + t @ pre.T
    names = asf.order()
    index = {name: k for k, name in enumerate(names)}
    starts = np.zeros((n, len(names), 3))
    ends = np.zeros((n, len(names), 3))
    rotations = np.zeros((n, len(names), 3, 3))
    for k, name in enumerate(names):
        b = asf.bones[name]
        if b.parent == "root":
            parent_rotation, start = root_rotation, root
        else:
            p = index[b.parent]
            parent_rotation, start = rotations[:, p], ends[:, p]
        c = euler(b.axis, b.axis_order)
        if b.dof:
            m = euler(amc.values[name][sel], "".join(d[1] for d in b.dof))
            local = c @ m @ c.T
        else:
            local = np.eye(3)
        rotations[:, k] = parent_rotation @ local
        starts[:, k] = start
        ends[:, k] = start + b.length * (rotations[:, k] @ b.direction)
    return Pose(names=names, root=root, starts=starts, ends=ends, rotations=rotations)
