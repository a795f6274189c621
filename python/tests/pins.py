"""Parts with curved and slanted faces for the decomposition tests, written as binary STL in
millimetres: pins whose tip edge is filleted (neither convex nor a stack of extrusions), a
rounded cross and a slotted circle, and the blind holes they fit (straight extrusions, which
pegtwin cuts exactly).

The cross: arms of half width `a` reaching `arm` from the axis, their outer corners rounded by
`r_out`, the corners between arms by `r_in`. Offsetting it by d gives the same family
(a + d, arm + d, r_out + d, r_in - d), so the hole's outline is the pin's grown by half the
clearance, and each layer of the pin's fillet is the outline shrunk by the fillet's inset. Every
outline is sampled with the same number of points per arc, so layers join point to point; caps
are fans from a point the outline is star-shaped about (checked).

The slotted circle: a disc of radius `radius` with a slot whose walls run along the radii at
+-`half_angle` (narrowing inward, so the outline is star-shaped about the axis) down to an arc of
radius `bottom`; the walls sit `shift` into the slot (out of it when negative: the fillet's
layers), the rim corners are rounded by `r_out`, the bottom corners by `r_in`. Offsetting it by d gives (radius + d, bottom + d, shift + d, r_out + d,
r_in - d): every rounding keeps its centre."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np

ARC_POINTS = 10


def arc(cx: float, cy: float, r: float, a0: float, a1: float,
        points: int = ARC_POINTS) -> list[tuple[float, float]]:
    return [
        (cx + r * math.cos(a0 + (a1 - a0) * k / (points - 1)),
         cy + r * math.sin(a0 + (a1 - a0) * k / (points - 1)))
        for k in range(points)
    ]


def rounded_cross(a: float, arm: float, r_out: float, r_in: float) -> np.ndarray:
    """The outline, counter-clockwise seen from +z (mm)."""
    quarter = (
        arc(arm - r_out, -a + r_out, r_out, -math.pi / 2, 0.0)
        + arc(arm - r_out, a - r_out, r_out, 0.0, math.pi / 2)
        + arc(a + r_in, a + r_in, r_in, -math.pi / 2, -math.pi)
    )
    points = []
    for q in range(4):
        c, s = math.cos(q * math.pi / 2), math.sin(q * math.pi / 2)
        points += [(c * x - s * y, s * x + c * y) for x, y in quarter]
    return np.array(points)


def polar(x: float, y: float) -> float:
    return math.atan2(y, x)


def slotted_circle(radius: float, bottom: float, shift: float, r_out: float, r_in: float,
                   half_angle: float = math.radians(15.0)) -> np.ndarray:
    """The outline, counter-clockwise seen from +z (mm), the slot along +x."""
    e = np.array([math.cos(half_angle), math.sin(half_angle)])
    n = np.array([-math.sin(half_angle), math.cos(half_angle)])  # into the upper half's material
    c_in = math.sqrt((bottom + r_in) ** 2 - (shift + r_in) ** 2) * e - (shift + r_in) * n
    c_out = math.sqrt((radius - r_out) ** 2 - (r_out - shift) ** 2) * e + (r_out - shift) * n
    a_in, a_out = polar(*c_in), polar(*c_out)
    upper = (
        arc(0.0, 0.0, bottom, 0.0, a_in)[:-1]
        + arc(*c_in, r_in, a_in + math.pi, polar(*n))
        + arc(*c_out, r_out, polar(*n) - math.pi, a_out)
        + arc(0.0, 0.0, radius, a_out, math.pi, 4 * ARC_POINTS)[1:-1]
    )
    return np.array(upper + [(-radius, 0.0)] + [(x, -y) for x, y in reversed(upper[1:])])


def check_star(outline: np.ndarray, centre: tuple[float, float]) -> None:
    """A fan from `centre` covers the outline once: its polar angle about `centre` only grows."""
    angles = np.unwrap([polar(x - centre[0], y - centre[1]) for x, y in outline])
    turns = (angles[-1] - angles[0]) / (2 * math.pi)
    assert np.all(np.diff(angles) > 0) and turns < 1, f"not star-shaped about {centre}"


def write_stl(path: Path, triangles: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> None:
    with open(path, "wb") as f:
        f.write(b"pegtwin test part".ljust(80, b" "))
        f.write(struct.pack("<I", len(triangles)))
        for a, b, c in triangles:
            n = np.cross(b - a, c - a)
            n = n / (np.linalg.norm(n) or 1.0)
            f.write(struct.pack("<12fH", *n, *a, *b, *c, 0))


def ring(outline: np.ndarray, z: float) -> list[np.ndarray]:
    return [np.array([x, y, z]) for x, y in outline]


def band(lower: list, upper: list, outward: bool) -> list:
    """The wall between two rings (lower below upper), facing away from the axis or toward it."""
    tris = []
    n = len(lower)
    for i in range(n):
        j = (i + 1) % n
        quad = [(lower[i], lower[j], upper[j]), (lower[i], upper[j], upper[i])]
        tris += quad if outward else [(p, r, q) for p, q, r in quad]
    return tris


def fan(points: list, up: bool, centre_xy: tuple[float, float] = (0.0, 0.0)) -> list:
    check_star(np.array([p[:2] for p in points]), centre_xy)
    centre = np.array([*centre_xy, points[0][2]])
    n = len(points)
    return [
        (centre, points[i], points[(i + 1) % n]) if up else (centre, points[(i + 1) % n], points[i])
        for i in range(n)
    ]


def cross(d: float) -> np.ndarray:
    """The test cross offset outward by d (mm): arms 8 wide reaching 12, corners rounded."""
    return rounded_cross(4.0 + d, 12.0 + d, 2.5 + d, 1.5 - d)


def slot(d: float) -> np.ndarray:
    """The test slotted circle offset outward by d (mm): 20 across, the slot 5 deep."""
    return slotted_circle(10.0 + d, 5.0 + d, d, 2.0 + d, 0.75 - d)


# Each shape, and a point its pin's outlines (inset by the fillet or not) are star-shaped about: the
# slotted circle's walls, moved out of the slot, turn back seen from the axis.
SHAPES = {"cross": (cross, (0.0, 0.0)), "slot": (slot, (-7.0, 0.0))}


def filleted_pin(path: Path, shape: str, fillet=1.5, height=40.0, layers=8) -> None:
    """The pin, tip centre at the origin, z up its axis; the tip edge a quarter circle."""
    outline, cap_centre = SHAPES[shape]
    rings = []
    for k in range(layers + 1):
        phi = (math.pi / 2) * k / layers
        z, inset = fillet * (1 - math.cos(phi)), fillet * (1 - math.sin(phi))
        rings.append(ring(outline(-inset), z))
    rings.append(ring(outline(0.0), height))
    tris = fan(rings[0], up=False, centre_xy=cap_centre)
    tris += fan(rings[-1], up=True, centre_xy=cap_centre)
    for lower, upper in zip(rings, rings[1:]):
        tris += band(lower, upper, outward=True)
    write_stl(path, tris)


def hole_block(path: Path, shape: str, clearance: float, depth=30.0, floor=8.0,
               half_size=25.0) -> None:
    """The block with the blind hole, mouth centre at the origin, z out of the hole."""
    outline = SHAPES[shape][0](clearance / 2)
    check_star(outline, (0.0, 0.0))
    square = np.array([p * half_size / max(abs(p[0]), abs(p[1])) for p in outline])
    mouth, bottom = ring(outline, 0.0), ring(outline, -depth)
    top, base = ring(square, 0.0), ring(square, -depth - floor)
    tris = band(bottom, mouth, outward=False) + fan(bottom, up=True)
    tris += band(base, top, outward=True) + fan(base, up=False)
    n = len(mouth)
    for i in range(n):
        j = (i + 1) % n
        tris += [(mouth[i], top[i], top[j]), (mouth[i], top[j], mouth[j])]
    write_stl(path, tris)
