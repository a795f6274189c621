//! The contact manifold drawn as the paper draws it (Fig. 3's reference manifold M): every contact
//! pose `hole_T_peg` as a point at its position, coloured by its orientation.
//!
//! One figure, two rows: on top the x-y-z scatter three times, coloured by roll, by pitch and by
//! yaw; below the three projections, each coloured by the rotation about the axis it looks along
//! (x-y by yaw, x-z by pitch, y-z by roll). Positions in mm, angles in deg, both in the hole
//! frame (z out of the hole, so insertion depth is negative z). Colours run along viridis from
//! each angle's 1st percentile (dark purple) to its 99th (yellow); the panel titles give the
//! ranges. A manifold larger than [`MAX_DRAWN_POSES`] is drawn through an even stride over its
//! points, and the title says how many are shown; the few poses outside the 0.1-99.9 % span of x,
//! y or z (stray contacts at the mouth) are left out, and the title says how many.

use super::ManifoldMeta;
use crate::error::Result;
use crate::figures::{self, DrawResult, err};
use crate::pose::Pose6;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;
use std::ops::Range;
use std::path::Path;

/// The most poses one panel draws (an even stride over larger manifolds keeps the SVG small).
pub const MAX_DRAWN_POSES: usize = 5_000;
/// Figure size, pixels.
const SIZE: (u32, u32) = (1500, 1000);
const AXIS_NAMES: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];

/// A pose as plotted: position mm, orientation deg.
type Drawn = [f64; 6];

/// Writes the figure of the contact poses `points` (`hole_T_peg`, m and rad) to `dir/{name}.png`
/// and `dir/{name}.svg`; `label` names them in the title (see [`label`]).
pub fn plot(points: &[Pose6], label: &str, dir: &Path, name: &str) -> Result<()> {
    let (drawn, outlying) = without_outliers(drawn_poses(points));
    let mut sample = if drawn.len() + outlying < points.len() {
        format!("{} of {} poses shown", drawn.len(), points.len())
    } else {
        format!("{} poses", points.len())
    };
    if outlying > 0 {
        sample += &format!(", {outlying} beyond the 0.1-99.9 % span of x, y or z left out");
    }
    let title = format!("Contact manifold: {label} ({sample})");
    figures::render(
        dir,
        name,
        SIZE,
        |a| draw(a, &title, &drawn),
        |a| draw(a, &title, &drawn),
    )
}

/// A manifold's name in a title: its geometry and clearance.
pub fn label(meta: &ManifoldMeta) -> String {
    match meta.clearance_m {
        Some(c) => format!("{} at {} mm", meta.geometry, c * 1e3),
        None => meta.geometry.clone(),
    }
}

/// The poses drawn (an even stride when there are more than [`MAX_DRAWN_POSES`]), mm and deg.
fn drawn_poses(points: &[Pose6]) -> Vec<Drawn> {
    let stride = points.len().div_ceil(MAX_DRAWN_POSES).max(1);
    points
        .iter()
        .step_by(stride)
        .map(Pose6::to_mm_deg)
        .collect()
}

/// The poses whose x, y and z lie within their 0.1-99.9 % span, and how many did not: a few
/// stray contacts at the mouth would otherwise stretch the axes and squeeze the manifold into a
/// corner.
fn without_outliers(poses: Vec<Drawn>) -> (Vec<Drawn>, usize) {
    let spans: Vec<Range<f64>> = (0..3)
        .map(|a| percentile_span(&poses, a, 0.001, 0.999))
        .collect();
    let total = poses.len();
    let kept: Vec<Drawn> = poses
        .into_iter()
        .filter(|p| (0..3).all(|a| spans[a].start <= p[a] && p[a] <= spans[a].end))
        .collect();
    let outlying = total - kept.len();
    (kept, outlying)
}

/// The axis range of column `axis` over `poses`: its extent, padded, and widened where it is
/// flat so that axes stay defined.
fn range(poses: &[Drawn], axis: usize) -> Range<f64> {
    let span = percentile_span(poses, axis, 0.0, 1.0);
    let pad = ((span.end - span.start) * 0.02).max(1e-3);
    (span.start - pad)..(span.end + pad)
}

/// The range the colours of `angle` span: its 1st to 99th percentile over `poses`, so that a few
/// outlying poses do not wash the rest into one colour (values beyond take the end colours).
fn colour_span(poses: &[Drawn], angle: usize) -> Range<f64> {
    percentile_span(poses, angle, 0.01, 0.99)
}

/// The `lo` to `hi` quantiles of column `axis` over `poses` (finite values), widened to 1 where
/// they meet.
fn percentile_span(poses: &[Drawn], axis: usize, lo: f64, hi: f64) -> Range<f64> {
    let mut v: Vec<f64> = poses
        .iter()
        .map(|p| p[axis])
        .filter(|a| a.is_finite())
        .collect();
    if v.is_empty() {
        return -1.0..1.0;
    }
    v.sort_unstable_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    let (lo, hi) = (at(lo), at(hi));
    if hi - lo < 1e-6 {
        (lo - 0.5)..(hi + 0.5)
    } else {
        lo..hi
    }
}

fn colour(value: f64, span: &Range<f64>) -> RGBColor {
    ViridisRGB::get_color_normalized(value.clamp(span.start, span.end), span.start, span.end)
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    poses: &[Drawn],
) -> DrawResult {
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 26)).map_err(err)?;
    let (top, bottom) = root.split_vertically(SIZE.1 * 11 / 20);
    for (area, angle) in top.split_evenly((1, 3)).iter().zip([3, 4, 5]) {
        draw_3d(area, poses, angle)?;
    }
    let projections = [(0, 1, 5), (0, 2, 4), (1, 2, 3)];
    for (area, &(h, v, angle)) in bottom.split_evenly((1, 3)).iter().zip(&projections) {
        draw_projection(area, poses, h, v, angle)?;
    }
    root.present().map_err(err)
}

/// The caption of a panel coloured by `angle`: its name and range.
fn colour_caption(poses: &[Drawn], angle: usize) -> String {
    let span = colour_span(poses, angle);
    format!(
        "{} {:.2} to {:.2} deg (1-99 %)",
        AXIS_NAMES[angle], span.start, span.end
    )
}

fn draw_3d<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    poses: &[Drawn],
    angle: usize,
) -> DrawResult {
    let span = colour_span(poses, angle);
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!(
                "x, y (floor), z (up), mm; colour {}",
                colour_caption(poses, angle)
            ),
            ("sans-serif", 17),
        )
        .margin(8)
        .build_cartesian_3d(range(poses, 0), range(poses, 2), range(poses, 1))
        .map_err(err)?;
    chart.with_projection(|mut p| {
        p.yaw = 0.7;
        p.pitch = 0.35;
        p.scale = 0.8;
        p.into_matrix()
    });
    chart
        .configure_axes()
        .label_style(("sans-serif", 12))
        .draw()
        .map_err(err)?;
    chart
        .draw_series(
            poses
                .iter()
                .map(|p| Circle::new((p[0], p[2], p[1]), 2, colour(p[angle], &span).filled())),
        )
        .map_err(err)?;
    Ok(())
}

fn draw_projection<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    poses: &[Drawn],
    h: usize,
    v: usize,
    angle: usize,
) -> DrawResult {
    let span = colour_span(poses, angle);
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!(
                "{}-{} (mm), colour {}",
                AXIS_NAMES[h],
                AXIS_NAMES[v],
                colour_caption(poses, angle)
            ),
            ("sans-serif", 17),
        )
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(50)
        .build_cartesian_2d(range(poses, h), range(poses, v))
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(format!("{} (mm)", AXIS_NAMES[h]))
        .y_desc(format!("{} (mm)", AXIS_NAMES[v]))
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    chart
        .draw_series(
            poses
                .iter()
                .map(|p| Circle::new((p[h], p[v]), 2, colour(p[angle], &span).filled())),
        )
        .map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_large_manifold_is_drawn_through_an_even_stride() {
        let points: Vec<Pose6> = (0..12_001)
            .map(|i| Pose6([i as f64 * 1e-6, 0.0, 0.0, 0.0, 0.0, 0.0]))
            .collect();
        let drawn = drawn_poses(&points);
        assert!(drawn.len() <= MAX_DRAWN_POSES, "{}", drawn.len());
        assert_eq!(drawn.len(), 12_001usize.div_ceil(3));
        assert!((drawn[1][0] - 3e-3).abs() < 1e-12);
    }

    #[test]
    fn a_stray_pose_does_not_stretch_the_axes() {
        let mut poses: Vec<Drawn> = (0..5000)
            .map(|i| {
                [
                    (i % 50) as f64 * 0.01,
                    (i / 50) as f64 * 0.01,
                    -1.0,
                    0.0,
                    0.0,
                    0.0,
                ]
            })
            .collect();
        poses.push([5.0, -5.0, 0.0, 0.0, 0.0, 0.0]);
        let (kept, outlying) = without_outliers(poses);
        assert_eq!(outlying, 1);
        assert!(range(&kept, 0).end < 0.6, "{:?}", range(&kept, 0));
    }

    #[test]
    fn a_flat_axis_gets_a_range_and_colours_stay_defined() {
        let poses = vec![[0.0, 1.0, 2.0, 0.5, 0.5, 0.5]; 3];
        let r = range(&poses, 3);
        assert!(r.start < 0.5 && r.end > 0.5);
        let c = colour_span(&poses, 3);
        assert!(c.start < 0.5 && c.end > 0.5);
        let _ = colour(0.5, &c);
    }
}
