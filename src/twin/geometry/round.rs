//! Round primitives (MuJoCo's `sphere`, `capsule`, `cylinder` and `ellipsoid` geoms) as convex
//! pieces: polyhedra with their vertices on the surface, each face standing at most a chord
//! error inside it. The deviation reported is measured on the piece, not assumed: for every
//! face, how far the true surface reaches beyond the face's plane (its support along the
//! face's normal against the piece's).

use super::planar::{P2, circle, sides_for_circle};
use super::solid::{ConvexPiece, P3, ZPlane};
use nalgebra::Vector3;
use std::f64::consts::PI;

/// A round primitive, centred at the origin, its axis (capsule, cylinder) along z; metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Round {
    Sphere {
        radius: f64,
    },
    /// A cylinder of half length `half_length` capped by hemispheres.
    Capsule {
        radius: f64,
        half_length: f64,
    },
    Cylinder {
        radius: f64,
        half_length: f64,
    },
    Ellipsoid {
        radii: Vector3<f64>,
    },
}

/// A primitive as a convex piece, and how far its faces stand inside the surface, m.
#[derive(Clone, Debug)]
pub struct Polygonised {
    pub piece: ConvexPiece,
    pub deviation_m: f64,
}

impl Round {
    /// The primitive with every length multiplied by `s`.
    pub fn scaled(&self, s: f64) -> Round {
        match *self {
            Round::Sphere { radius } => Round::Sphere { radius: radius * s },
            Round::Capsule {
                radius,
                half_length,
            } => Round::Capsule {
                radius: radius * s,
                half_length: half_length * s,
            },
            Round::Cylinder {
                radius,
                half_length,
            } => Round::Cylinder {
                radius: radius * s,
                half_length: half_length * s,
            },
            Round::Ellipsoid { radii } => Round::Ellipsoid { radii: radii * s },
        }
    }

    /// MuJoCo's name of the geom type.
    pub fn name(&self) -> &'static str {
        match self {
            Round::Sphere { .. } => "sphere",
            Round::Capsule { .. } => "capsule",
            Round::Cylinder { .. } => "cylinder",
            Round::Ellipsoid { .. } => "ellipsoid",
        }
    }

    /// Its sizes as MuJoCo's `size` lists them (radius, half length; or the radii): all must be
    /// above 0.
    pub fn sizes(&self) -> Vec<f64> {
        match *self {
            Round::Sphere { radius } => vec![radius],
            Round::Capsule {
                radius,
                half_length,
            }
            | Round::Cylinder {
                radius,
                half_length,
            } => vec![radius, half_length],
            Round::Ellipsoid { radii } => radii.iter().copied().collect(),
        }
    }

    /// The piece whose faces stand at most `chord_m` inside the surface. `None` for a size of
    /// 0 or less.
    pub fn polygonise(&self, chord_m: f64) -> Option<Polygonised> {
        if !self.sizes().iter().all(|s| *s > 0.0) {
            return None;
        }
        let piece = match *self {
            Round::Cylinder {
                radius,
                half_length,
            } => {
                let ring: Vec<P2> =
                    circle(P2::origin(), radius, sides_for_circle(radius, chord_m), 0.0);
                ConvexPiece::slab(&ring, ZPlane::flat(-half_length), ZPlane::flat(half_length))
            }
            _ => ConvexPiece::from_points(&self.points(chord_m))?,
        };
        let deviation_m = piece
            .face_normals
            .iter()
            .map(|n| {
                let reached = piece
                    .vertices
                    .iter()
                    .map(|v| v.coords.dot(n))
                    .fold(f64::MIN, f64::max);
                self.support(n) - reached
            })
            .fold(0.0, f64::max);
        Some(Polygonised { piece, deviation_m })
    }

    /// How far the primitive reaches along the unit direction `n`, m.
    fn support(&self, n: &Vector3<f64>) -> f64 {
        match *self {
            Round::Sphere { radius } => radius,
            Round::Capsule {
                radius,
                half_length,
            } => radius + half_length * n.z.abs(),
            Round::Cylinder {
                radius,
                half_length,
            } => radius * n.xy().norm() + half_length * n.z.abs(),
            Round::Ellipsoid { radii } => radii.component_mul(n).norm(),
        }
    }

    /// Points on the surface: rings of latitude, each a circle fine enough for the chord error
    /// (half of it on each of the two directions a face spans).
    fn points(&self, chord_m: f64) -> Vec<P3> {
        let (radius, stretch, half_length) = match *self {
            Round::Sphere { radius } => (radius, Vector3::repeat(1.0), 0.0),
            Round::Capsule {
                radius,
                half_length,
            }
            | Round::Cylinder {
                radius,
                half_length,
            } => (radius, Vector3::repeat(1.0), half_length),
            Round::Ellipsoid { radii } => (radii.max(), radii / radii.max(), 0.0),
        };
        let sides = sides_for_circle(radius, chord_m / 2.0);
        let rings = sides.div_ceil(4) * 2;
        let mut points = Vec::new();
        for k in 0..=rings {
            let polar = PI * k as f64 / rings as f64;
            let z = radius * polar.cos();
            let r = radius * polar.sin();
            // The capsule's hemispheres move apart by its cylinder (the equator taken on each).
            let shifts: &[f64] = match (half_length > 0.0, 2 * k == rings) {
                (false, _) => &[0.0],
                (true, true) => &[half_length, -half_length],
                (true, false) if 2 * k < rings => &[half_length],
                (true, false) => &[-half_length],
            };
            let ring: Vec<P2> = if k == 0 || k == rings {
                vec![P2::origin()]
            } else {
                circle(P2::origin(), r, sides, 0.0)
            };
            for shift in shifts {
                points.extend(
                    ring.iter().map(|p| {
                        P3::new(p.x * stretch.x, p.y * stretch.y, (z + shift) * stretch.z)
                    }),
                );
            }
        }
        points
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitives_stand_within_the_chord_error() {
        let chord = 2.5e-6;
        for round in [
            Round::Sphere { radius: 0.01 },
            Round::Capsule {
                radius: 0.004,
                half_length: 0.02,
            },
            Round::Cylinder {
                radius: 0.006,
                half_length: 0.015,
            },
            Round::Ellipsoid {
                radii: Vector3::new(0.01, 0.005, 0.02),
            },
        ] {
            let p = round.polygonise(chord).unwrap();
            assert!(p.deviation_m <= chord, "{round:?}: {}", p.deviation_m);
            assert!(p.deviation_m > 0.0, "{round:?}");
            // On the surface, to the hull's single precision.
            if let Round::Ellipsoid { radii } = round {
                for v in &p.piece.vertices {
                    let off = v.coords.component_div(&radii).norm() - 1.0;
                    assert!(off.abs() < 1e-7, "{round:?}: {v}");
                }
            }
        }
        assert!(Round::Sphere { radius: 0.0 }.polygonise(chord).is_none());
    }
}
