//! The picture that tells whether a registration converged (paper IV-D, Fig. 3 "register"): the
//! trial's contact poses over the reference manifold, seen from the hole frame the robot believed
//! before registering (red) and from the estimated one (green). A registration that converged
//! lays the green poses on the manifold (grey); one that locked onto a wrong basin leaves them
//! beside it.

use super::RegistrationRecord;
use crate::error::Result;
use crate::figures::{self, DrawResult, err};
use crate::method::manifold::Manifold;
use crate::pose::{Iso, Pose6};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::ops::Range;

/// The panel's size, pixels.
const SIZE: (u32, u32) = (1200, 380);
/// The most manifold poses drawn (an even stride over larger manifolds).
const MAX_MANIFOLD_POSES: usize = 4_000;
/// The projections drawn: (horizontal, vertical) columns of a pose in mm and deg.
const PROJECTIONS: [(usize, usize); 3] = [(0, 1), (0, 2), (1, 5)];
const AXIS_NAMES: [&str; 6] = [
    "x (mm)",
    "y (mm)",
    "z (mm)",
    "roll (deg)",
    "pitch (deg)",
    "yaw (deg)",
];

/// The panel as a PNG image.
pub fn png(manifold: &Manifold, reg: &RegistrationRecord) -> Result<Vec<u8>> {
    let stride = manifold.points.len().div_ceil(MAX_MANIFOLD_POSES).max(1);
    let reference: Vec<[f64; 6]> = manifold
        .points
        .iter()
        .step_by(stride)
        .map(Pose6::to_mm_deg)
        .collect();
    let before = in_frame(&reg.observations, &reg.believed);
    let after = reg
        .estimate
        .map(|e| in_frame(&reg.observations, &e))
        .unwrap_or_default();
    figures::png_bytes(SIZE, |a| draw(a, &reference, &before, &after))
}

/// The contact poses `base_T_tcp` seen from the hole frame `base_T_hole`, mm and deg.
fn in_frame(observations: &[Pose6], base_t_hole: &Iso) -> Vec<[f64; 6]> {
    let inv = base_t_hole.inverse();
    observations
        .iter()
        .map(|o| Pose6::from_iso(&(inv * o.to_iso())).to_mm_deg())
        .collect()
}

/// The range of column `axis` over every set drawn, padded.
fn range(sets: &[&[[f64; 6]]], axis: usize) -> Range<f64> {
    let (lo, hi) = sets
        .iter()
        .flat_map(|s| s.iter())
        .map(|p| p[axis])
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !(lo.is_finite() && hi.is_finite()) {
        return -1.0..1.0;
    }
    let pad = ((hi - lo) * 0.04).max(0.05);
    (lo - pad)..(hi + pad)
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    reference: &[[f64; 6]],
    before: &[[f64; 6]],
    after: &[[f64; 6]],
) -> DrawResult {
    root.fill(&WHITE).map_err(err)?;
    let title = if after.is_empty() {
        "Contact poses in the believed hole frame (red) over the reference manifold (grey)"
    } else {
        "Contact poses before registration (red) and after (green) over the reference manifold (grey)"
    };
    let root = root.titled(title, ("sans-serif", 18)).map_err(err)?;
    let sets: [&[[f64; 6]]; 3] = [reference, before, after];
    for (area, &(h, v)) in root.split_evenly((1, 3)).iter().zip(&PROJECTIONS) {
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(48)
            .build_cartesian_2d(range(&sets, h), range(&sets, v))
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(AXIS_NAMES[h])
            .y_desc(AXIS_NAMES[v])
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(err)?;
        let styles = [
            (reference, RGBColor(170, 170, 170), 1),
            (before, RGBColor(210, 40, 40), 2),
            (after, RGBColor(20, 150, 60), 2),
        ];
        for (points, colour, r) in styles {
            chart
                .draw_series(
                    points
                        .iter()
                        .map(|p| Circle::new((p[h], p[v]), r, colour.filled())),
                )
                .map_err(err)?;
        }
    }
    root.present().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::method::manifold::synthetic::SyntheticPair;
    use crate::method::manifold::{ManifoldMeta, UNITS};
    use crate::pose::PoseMetric;

    #[test]
    fn the_panel_is_a_png_of_its_size() {
        let pair = SyntheticPair::square(0.02, 0.5e-3);
        let points = pair.sample_contacts(2000, [0.002, 0.010], 1);
        let meta = ManifoldMeta {
            geometry: pair.name.clone(),
            clearance_m: Some(pair.clearance_m),
            units: UNITS.into(),
            metric: PoseMetric::default(),
            normal_k: 12,
            source: "test".into(),
            seed: Some(1),
        };
        let hole = Iso::translation(0.5, 0.0, 0.1);
        let observations: Vec<Pose6> = points[..200]
            .iter()
            .map(|p| Pose6::from_iso(&(hole * p.to_iso())))
            .collect();
        let manifold = Manifold::from_points(points, meta).unwrap();
        let record = RegistrationRecord {
            observations,
            believed: Iso::translation(0.501, 0.0, 0.1),
            estimate: Some(hole),
        };
        let png = png(&manifold, &record).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        let (w, h) = (
            u32::from_be_bytes(png[16..20].try_into().unwrap()),
            u32::from_be_bytes(png[20..24].try_into().unwrap()),
        );
        assert_eq!((w, h), SIZE);
    }
}
