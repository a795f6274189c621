//! The five built-in peg cross-sections, parametric in an outward offset `d` (metres).
//!
//! Each profile is a union of convex polygons. Offsetting every piece by `d` offsets the union:
//! straight faces move by `d` along their normal with sharp corners (a CAD "offset face", so the
//! clearance between two parallel faces is exactly `d`), round features grow their radius by `d`,
//! and involute gear flanks become the involute shifted by `d / r_base`, which is their exact
//! parallel curve. The hole cavity is the profile offset by half the clearance (ISO fits: the
//! clearance is diametral).

use super::planar::{P2, circle, circle_through, convex_hull, rect, sides_for_circle};
use serde::Serialize;

/// Millimetres to metres.
const MM: f64 = 1e-3;

/// The built-in peg/hole pairs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Builtin {
    Cross,
    Extrusion,
    Plug3,
    Key,
    Gear,
}

/// A named dimension of a built-in, for `geometry list`.
#[derive(Clone, Debug, Serialize)]
pub struct Dimension {
    pub name: &'static str,
    pub value_mm: f64,
}

impl Builtin {
    pub const ALL: [Builtin; 5] = [
        Builtin::Cross,
        Builtin::Extrusion,
        Builtin::Plug3,
        Builtin::Key,
        Builtin::Gear,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Builtin::Cross => "cross",
            Builtin::Extrusion => "extrusion",
            Builtin::Plug3 => "plug3",
            Builtin::Key => "key",
            Builtin::Gear => "gear",
        }
    }

    /// Looks a built-in up by name.
    pub fn from_name(name: &str) -> Option<Builtin> {
        Builtin::ALL.into_iter().find(|b| b.name() == name)
    }

    pub fn description(self) -> &'static str {
        match self {
            Builtin::Cross => "plus-shaped peg, 25 mm span, 5 mm arms",
            Builtin::Extrusion => {
                "25 mm square T-slot extrusion profile, one undercut slot on each side"
            }
            Builtin::Plug3 => {
                "three-pin mains plug: two 6.35 x 1.5 mm blades and a 4.8 mm round ground pin"
            }
            Builtin::Key => "16 mm round shaft with a 5 x 5 mm parallel key",
            Builtin::Gear => "spur gear, 12 teeth, module 2, 20 deg pressure angle, 28 mm outside",
        }
    }

    /// The profile's defining dimensions, millimetres.
    pub fn dimensions(self) -> Vec<Dimension> {
        let d = |name, value_mm| Dimension { name, value_mm };
        match self {
            Builtin::Cross => vec![d("span", 25.0), d("arm_width", 5.0)],
            Builtin::Extrusion => vec![
                d("size", EXT_HALF * 2.0),
                d("slot_opening", EXT_SLOT_HALF * 2.0),
                d("lip_thickness", EXT_HALF - EXT_LIP_INNER),
                d("chamber_width", EXT_CHAMBER_HALF * 2.0),
                d("chamber_depth", EXT_LIP_INNER - EXT_CORE_HALF),
            ],
            Builtin::Plug3 => vec![
                d("blade_length", PLUG_BLADE_LEN),
                d("blade_thickness", PLUG_BLADE_THICK),
                d("blade_spacing", PLUG_BLADE_SPACING),
                d("ground_pin_diameter", PLUG_PIN_DIA),
                d("ground_pin_offset", -PLUG_PIN_Y),
            ],
            Builtin::Key => vec![
                d("shaft_diameter", KEY_SHAFT_DIA),
                d("key_width", KEY_WIDTH),
                d("key_height", KEY_HEIGHT),
                d("keyway_depth_in_shaft", KEY_SHAFT_DEPTH),
            ],
            // The tooth count and pressure angle are not lengths: the description gives them.
            Builtin::Gear => vec![
                d("module", GEAR_MODULE),
                d("outside_diameter", GEAR_MODULE * (GEAR_TEETH as f64 + 2.0)),
                d("root_diameter", GEAR_MODULE * (GEAR_TEETH as f64 - 2.5)),
            ],
        }
    }

    /// Convex pieces of the profile offset outward by `d` metres, with round features polygonised
    /// so that the chord error is at most `tol` metres at any offset up to `d_max`.
    pub fn pieces(self, d: f64, tol: f64, d_max: f64) -> Vec<Vec<P2>> {
        match self {
            Builtin::Cross => cross(d),
            Builtin::Extrusion => extrusion(d),
            Builtin::Plug3 => plug3(d, tol, d_max),
            Builtin::Key => key(d, tol),
            Builtin::Gear => gear(d, tol),
        }
    }
}

fn grown(x0: f64, y0: f64, x1: f64, y1: f64, d: f64) -> Vec<P2> {
    rect(x0 * MM - d, y0 * MM - d, x1 * MM + d, y1 * MM + d)
}

/// Two overlapping bars.
fn cross(d: f64) -> Vec<Vec<P2>> {
    vec![
        grown(-12.5, -2.5, 12.5, 2.5, d),
        grown(-2.5, -12.5, 2.5, 12.5, d),
    ]
}

const EXT_HALF: f64 = 12.5;
const EXT_CORE_HALF: f64 = 7.0;
const EXT_LIP_INNER: f64 = 10.5;
const EXT_CHAMBER_HALF: f64 = 5.5;
const EXT_SLOT_HALF: f64 = 3.0;

/// A square core, four corner blocks and eight lips that overhang the four slot chambers.
fn extrusion(d: f64) -> Vec<Vec<P2>> {
    let mut pieces = vec![grown(
        -EXT_CORE_HALF,
        -EXT_CORE_HALF,
        EXT_CORE_HALF,
        EXT_CORE_HALF,
        d,
    )];
    for (sx, sy) in [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)] {
        let span = |a: f64, b: f64, s: f64| if s > 0.0 { (a, b) } else { (-b, -a) };
        let (cx0, cx1) = span(EXT_CHAMBER_HALF, EXT_HALF, sx);
        let (cy0, cy1) = span(EXT_CHAMBER_HALF, EXT_HALF, sy);
        pieces.push(grown(cx0, cy0, cx1, cy1, d));
        // The lip on the x side of this corner, running over the corner block.
        let (lx0, lx1) = span(EXT_LIP_INNER, EXT_HALF, sx);
        let (ly0, ly1) = span(EXT_SLOT_HALF, EXT_HALF, sy);
        pieces.push(grown(lx0, ly0, lx1, ly1, d));
        // The lip on the y side.
        let (mx0, mx1) = span(EXT_SLOT_HALF, EXT_HALF, sx);
        let (my0, my1) = span(EXT_LIP_INNER, EXT_HALF, sy);
        pieces.push(grown(mx0, my0, mx1, my1, d));
    }
    pieces
}

const PLUG_BLADE_LEN: f64 = 6.35;
const PLUG_BLADE_THICK: f64 = 1.5;
const PLUG_BLADE_SPACING: f64 = 12.7;
const PLUG_BLADE_Y: f64 = 3.0;
const PLUG_PIN_DIA: f64 = 4.8;
const PLUG_PIN_Y: f64 = -6.0;

/// Two flat blades and a round ground pin: three separate pegs on one body.
fn plug3(d: f64, tol: f64, d_max: f64) -> Vec<Vec<P2>> {
    let (hx, hy) = (PLUG_BLADE_THICK / 2.0, PLUG_BLADE_LEN / 2.0);
    let bx = PLUG_BLADE_SPACING / 2.0;
    let r = PLUG_PIN_DIA / 2.0 * MM;
    let sides = sides_for_circle(r + d_max, tol);
    vec![
        grown(-bx - hx, PLUG_BLADE_Y - hy, -bx + hx, PLUG_BLADE_Y + hy, d),
        grown(bx - hx, PLUG_BLADE_Y - hy, bx + hx, PLUG_BLADE_Y + hy, d),
        circle(P2::new(0.0, PLUG_PIN_Y * MM), r + d, sides, 0.0),
    ]
}

const KEY_SHAFT_DIA: f64 = 16.0;
const KEY_WIDTH: f64 = 5.0;
const KEY_HEIGHT: f64 = 5.0;
/// Shaft keyway depth t1 for a 16 mm shaft (DIN 6885-1).
const KEY_SHAFT_DEPTH: f64 = 3.0;

/// A round shaft and the key standing 2 mm proud of it.
fn key(d: f64, tol: f64) -> Vec<Vec<P2>> {
    let r = KEY_SHAFT_DIA / 2.0 * MM + d;
    let half_w = KEY_WIDTH / 2.0 * MM + d;
    let crossing = (r * r - half_w * half_w).sqrt().atan2(half_w);
    let key_bottom = KEY_SHAFT_DIA / 2.0 - KEY_SHAFT_DEPTH;
    vec![
        circle_through(
            P2::origin(),
            r,
            &[crossing, std::f64::consts::PI - crossing],
            tol,
        ),
        grown(
            -KEY_WIDTH / 2.0,
            key_bottom,
            KEY_WIDTH / 2.0,
            key_bottom + KEY_HEIGHT,
            d,
        ),
    ]
}

const GEAR_TEETH: usize = 12;
const GEAR_MODULE: f64 = 2.0;
const GEAR_PRESSURE_ANGLE_DEG: f64 = 20.0;

/// Smallest radius of curvature of the modelled involute flank, metres.
const INVOLUTE_MIN_CURVATURE_M: f64 = 0.5e-3;

/// Involute function inv(a) = tan(a) - a.
fn involute(a: f64) -> f64 {
    a.tan() - a
}

/// A root disc and twelve convex teeth. Each flank is an involute of the base circle above it and
/// a straight line parallel to the tooth's radial line below it (no root fillet).
fn gear(d: f64, tol: f64) -> Vec<Vec<P2>> {
    let z = GEAR_TEETH as f64;
    let m = GEAR_MODULE * MM;
    let alpha = GEAR_PRESSURE_ANGLE_DEG.to_radians();
    let r_pitch = m * z / 2.0;
    let r_base = r_pitch * alpha.cos();
    let r_tip = r_pitch + m + d;
    let r_root = r_pitch - 1.25 * m + d;
    // Half-angle of the tooth at the base circle (tooth thickness at the pitch circle is pi m / 2),
    // widened by d / r_base: the parallel curve of an involute at distance d.
    let psi_base = std::f64::consts::PI / (2.0 * z) + involute(alpha) + d / r_base;
    let flank_angle = |rho: f64| psi_base - involute((r_base / rho).acos());
    let lower_flank_half = psi_base - d / r_base;
    let rho_start = r_pitch - 1.25 * m - 1.0 * MM;
    let rho_involute = (r_base * r_base + INVOLUTE_MIN_CURVATURE_M.powi(2)).sqrt();
    // Half a tooth on the tooth axis at angle 0, from the lower flank up to the middle of the tip.
    let polar = |rho: f64, ang: f64| P2::new(rho * ang.cos(), rho * ang.sin());
    let radial_dir = nalgebra::Vector2::new(lower_flank_half.cos(), lower_flank_half.sin());
    let side = nalgebra::Vector2::new(-radial_dir.y, radial_dir.x);
    // Straight lower flank (the radial line moved by d sideways) up to where the involute's
    // radius of curvature reaches INVOLUTE_MIN_CURVATURE_M (the segment stays within a micrometre
    // of the involute below that point, and chamfers do not meet the involute's cusp), then the
    // involute flank, then the tip arc.
    let mut half = vec![P2::origin() + radial_dir * rho_start + side * d];
    // The involute in its roll angle t (radius r_base sqrt(1 + t^2)): equal steps in t turn the
    // flank by equal angles, and the chord error r_base t dt^2 / 8 is largest at the tip.
    let roll = |rho: f64| ((rho / r_base).powi(2) - 1.0).sqrt();
    let (t0, t1) = (roll(rho_involute), roll(r_tip));
    let steps = ((t1 - t0) / (8.0 * tol / (r_base * t1)).sqrt())
        .ceil()
        .max(1.0) as usize;
    half.extend((0..=steps).map(|k| {
        let t = t0 + (t1 - t0) * k as f64 / steps as f64;
        polar(r_base * (1.0 + t * t).sqrt(), psi_base - (t - t.atan()))
    }));
    let tip_half = flank_angle(r_tip);
    let tip_steps = (tip_half / (2.0 * (1.0 - tol / r_tip).acos()))
        .ceil()
        .max(1.0) as usize;
    half.extend(
        (1..=tip_steps).map(|k| polar(r_tip, tip_half * (1.0 - k as f64 / tip_steps as f64))),
    );
    // Where the first flank segment crosses the root circle: the root circle gets a vertex there.
    let (a, b) = (half[0], half[1]);
    let dir = b - a;
    let (qa, qb, qc) = (
        dir.norm_squared(),
        2.0 * a.coords.dot(&dir),
        a.coords.norm_squared() - r_root * r_root,
    );
    let t = (-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
    let cross_pt = a + dir * t;
    let crossing_half = cross_pt.y.atan2(cross_pt.x);
    let mut tooth = half.clone();
    tooth.extend(half.iter().map(|p| P2::new(p.x, -p.y)));
    let tooth = convex_hull(&tooth);
    let axes: Vec<f64> = (0..GEAR_TEETH)
        .map(|k| std::f64::consts::TAU * k as f64 / z)
        .collect();
    let crossings: Vec<f64> = axes
        .iter()
        .flat_map(|axis| [axis - crossing_half, axis + crossing_half])
        .collect();
    let mut pieces = vec![circle_through(P2::origin(), r_root, &crossings, tol)];
    for axis in axes {
        let (c, s) = (axis.cos(), axis.sin());
        pieces.push(
            tooth
                .iter()
                .map(|p| P2::new(c * p.x - s * p.y, s * p.x + c * p.y))
                .collect(),
        );
    }
    pieces
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::geometry::planar::{signed_area, union};

    #[test]
    fn every_piece_is_convex_and_counter_clockwise() {
        for b in Builtin::ALL {
            for piece in b.pieces(0.05e-3, 2.5e-6, 0.6e-3) {
                assert!(signed_area(&piece) > 0.0, "{}", b.name());
                assert_eq!(convex_hull(&piece).len(), piece.len(), "{}", b.name());
            }
        }
    }

    #[test]
    fn cross_area_matches_its_dimensions_and_offset() {
        let area = |d: f64| -> f64 { union(&cross(d)).iter().map(|r| r.area()).sum() };
        assert!((area(0.0) - 225e-6).abs() < 1e-12);
        // Offset d adds perimeter * d + 4 sharp convex corners' squares.
        let d = 0.05e-3;
        let expected = 225e-6 + 100e-3 * d + 4.0 * d * d * 2.0 - 4.0 * d * d;
        assert!(
            (area(d) - expected).abs() < 1e-12,
            "{} vs {}",
            area(d),
            expected
        );
    }

    #[test]
    fn gear_outside_diameter_is_28_mm_and_teeth_are_not_pointed() {
        let pieces = gear(0.0, 2.5e-6);
        let max_r = pieces
            .iter()
            .flatten()
            .map(|p| p.coords.norm())
            .fold(0.0, f64::max);
        assert!((max_r - 14e-3).abs() < 1e-9, "{max_r}");
        // Tip land of a tooth: the tip arc spans more than 1 mm.
        let tooth = &pieces[1];
        let tip: Vec<&P2> = tooth
            .iter()
            .filter(|p| (p.coords.norm() - 14e-3).abs() < 1e-9)
            .collect();
        let span = tip.iter().map(|p| p.y).fold(f64::MIN, f64::max)
            - tip.iter().map(|p| p.y).fold(f64::MAX, f64::min);
        assert!(span > 1.0e-3, "tip land {span}");
    }
}
