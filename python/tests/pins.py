"""Parts with curved and slanted faces for the decomposition tests, written as binary STL in
millimetres: a rounded cross pin whose tip edge is filleted (neither convex nor a stack of
extrusions), and the blind hole it fits (a straight extrusion, which pegtwin cuts exactly).

The cross: arms of half width `a` reaching `arm` from the axis, their outer corners rounded by
`r_out`, the corners between arms by `r_in`. Offsetting it by d gives the same family
(a + d, arm + d, r_out + d, r_in - d), so the hole's outline is the pin's grown by half the
clearance, and each layer of the pin's fillet is the outline shrunk by the fillet's inset. Every
outline is sampled with the same number of points per arc, so layers join point to point; the
outlines are star-shaped about the axis, so caps are fans from the centre."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np

ARC_POINTS = 10


def arc(cx: float, cy: float, r: float, a0: float, a1: float) -> list[tuple[float, float]]:
    return [
        (cx + r * math.cos(a0 + (a1 - a0) * k / (ARC_POINTS - 1)),
         cy + r * math.sin(a0 + (a1 - a0) * k / (ARC_POINTS - 1)))
        for k in range(ARC_POINTS)
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


def fan(points: list, up: bool) -> list:
    centre = np.mean(points, axis=0) * 0.0 + np.array([0.0, 0.0, points[0][2]])
    n = len(points)
    return [
        (centre, points[i], points[(i + 1) % n]) if up else (centre, points[(i + 1) % n], points[i])
        for i in range(n)
    ]


def filleted_cross_pin(path: Path, a=4.0, arm=12.0, r_out=2.5, r_in=1.5, fillet=1.5,
                       height=40.0, layers=8) -> None:
    """The pin, tip centre at the origin, z up its axis; the tip edge a quarter circle."""
    rings = []
    for k in range(layers + 1):
        phi = (math.pi / 2) * k / layers
        z, inset = fillet * (1 - math.cos(phi)), fillet * (1 - math.sin(phi))
        rings.append(ring(rounded_cross(a - inset, arm - inset, r_out - inset, r_in + inset), z))
    rings.append(ring(rounded_cross(a, arm, r_out, r_in), height))
    tris = fan(rings[0], up=False) + fan(rings[-1], up=True)
    for lower, upper in zip(rings, rings[1:]):
        tris += band(lower, upper, outward=True)
    write_stl(path, tris)


def cross_hole_block(path: Path, clearance: float, a=4.0, arm=12.0, r_out=2.5, r_in=1.5,
                     depth=30.0, floor=8.0, half_size=25.0) -> None:
    """The block with the blind hole, mouth centre at the origin, z out of the hole."""
    g = clearance / 2
    outline = rounded_cross(a + g, arm + g, r_out + g, r_in - g)
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
