//! The query dispatcher pegtwin gives rapier: contact manifolds between convex polyhedra from the
//! exact separating-axis test ([`super::sat`]), compound pairs (a peg and its hole) through the
//! candidate list of [`super::compound`], and rapier's defaults for every other shape.

use super::compound::compound_manifolds;
use super::sat::{SatPiece, TurnedPieces, sat_manifold};
use rapier3d::parry::math::{Pose, Real, Vector};
use rapier3d::parry::query::details::{NormalConstraints, contact_manifolds_composite_shape_shape};
use rapier3d::parry::query::{
    ClosestPoints, Contact, ContactManifold, ContactManifoldsWorkspace, DefaultQueryDispatcher,
    NonlinearRigidMotion, PersistentQueryDispatcher, QueryDispatcher, ShapeCastHit,
    ShapeCastOptions, ShapeDistance, ShapeIntersection, Unsupported,
};
use rapier3d::parry::shape::Shape;

/// The query dispatcher pegtwin gives rapier: exact SAT manifolds for pairs of convex polyhedra,
/// rapier's defaults for everything else.
pub struct ExactConvexDispatcher;

impl QueryDispatcher for ExactConvexDispatcher {
    fn intersection_test(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
    ) -> Result<ShapeIntersection, Unsupported> {
        DefaultQueryDispatcher.intersection_test(pos12, g1, g2)
    }

    fn distance(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
    ) -> Result<ShapeDistance, Unsupported> {
        DefaultQueryDispatcher.distance(pos12, g1, g2)
    }

    fn contact(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
        prediction: Real,
    ) -> Result<Option<Contact>, Unsupported> {
        DefaultQueryDispatcher.contact(pos12, g1, g2, prediction)
    }

    fn closest_points(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
        max_dist: Real,
    ) -> Result<ClosestPoints, Unsupported> {
        DefaultQueryDispatcher.closest_points(pos12, g1, g2, max_dist)
    }

    fn cast_shapes(
        &self,
        pos12: &Pose,
        local_vel12: Vector,
        g1: &dyn Shape,
        g2: &dyn Shape,
        options: ShapeCastOptions,
    ) -> Result<Option<ShapeCastHit>, Unsupported> {
        DefaultQueryDispatcher.cast_shapes(pos12, local_vel12, g1, g2, options)
    }

    fn cast_shapes_nonlinear(
        &self,
        motion1: &NonlinearRigidMotion,
        g1: &dyn Shape,
        motion2: &NonlinearRigidMotion,
        g2: &dyn Shape,
        start_time: Real,
        end_time: Real,
        stop_at_penetration: bool,
    ) -> Result<Option<ShapeCastHit>, Unsupported> {
        DefaultQueryDispatcher.cast_shapes_nonlinear(
            motion1,
            g1,
            motion2,
            g2,
            start_time,
            end_time,
            stop_at_penetration,
        )
    }
}

impl<M, C> PersistentQueryDispatcher<M, C> for ExactConvexDispatcher
where
    M: Default + Clone + Send + Sync + 'static,
    C: Default + Copy + Send + Sync + 'static,
    DefaultQueryDispatcher: PersistentQueryDispatcher<M, C>,
{
    fn contact_manifolds(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
        prediction: Real,
        manifolds: &mut Vec<ContactManifold<M, C>>,
        workspace: &mut Option<ContactManifoldsWorkspace>,
    ) -> Result<(), Unsupported> {
        match (g1.as_composite_shape(), g2.as_composite_shape()) {
            (Some(c1), Some(c2)) => {
                compound_manifolds(pos12, c1, c2, prediction, manifolds, workspace);
                Ok(())
            }
            (Some(c1), None) => {
                contact_manifolds_composite_shape_shape(
                    self, pos12, c1, g2, prediction, manifolds, workspace, false,
                );
                Ok(())
            }
            (None, Some(c2)) => {
                contact_manifolds_composite_shape_shape(
                    self,
                    &pos12.inverse(),
                    c2,
                    g1,
                    prediction,
                    manifolds,
                    workspace,
                    true,
                );
                Ok(())
            }
            (None, None) if is_polyhedron_pair(g1, g2) => {
                if manifolds.is_empty() {
                    manifolds.push(ContactManifold::new());
                }
                self.contact_manifold_convex_convex(
                    pos12,
                    g1,
                    g2,
                    None,
                    None,
                    prediction,
                    &mut manifolds[0],
                )
            }
            (None, None) => DefaultQueryDispatcher
                .contact_manifolds(pos12, g1, g2, prediction, manifolds, workspace),
        }
    }

    fn contact_manifold_convex_convex(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
        normal_constraints1: Option<&dyn NormalConstraints>,
        normal_constraints2: Option<&dyn NormalConstraints>,
        prediction: Real,
        manifold: &mut ContactManifold<M, C>,
    ) -> Result<(), Unsupported> {
        match (g1.as_convex_polyhedron(), g2.as_convex_polyhedron()) {
            (Some(a), Some(b)) => {
                let (sa, sb) = (SatPiece::new(a), SatPiece::new(b));
                let mut turned = TurnedPieces::default();
                sat_manifold(
                    pos12,
                    (a, &sa),
                    (b, &sb, 0),
                    prediction,
                    manifold,
                    &mut turned,
                );
                Ok(())
            }
            _ => DefaultQueryDispatcher.contact_manifold_convex_convex(
                pos12,
                g1,
                g2,
                normal_constraints1,
                normal_constraints2,
                prediction,
                manifold,
            ),
        }
    }
}

fn is_polyhedron_pair(g1: &dyn Shape, g2: &dyn Shape) -> bool {
    g1.as_convex_polyhedron().is_some() && g2.as_convex_polyhedron().is_some()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::geometry::{Builtin, build_builtin};
    use crate::twin::physics::compound::compound_manifolds;
    use crate::twin::physics::{compound_collider, pose32};
    use nalgebra::{Isometry3, Vector3};
    use rapier3d::parry::query::details::contact_manifolds_composite_shape_composite_shape;

    type Manifolds = Vec<ContactManifold<(), ()>>;

    /// The pieces in contact and their points (bit patterns), sorted.
    fn contacts(manifolds: &Manifolds) -> Vec<(u32, u32, Vec<[u32; 4]>)> {
        let mut out: Vec<_> = manifolds
            .iter()
            .filter(|m| !m.points.is_empty())
            .map(|m| {
                let points = m
                    .points
                    .iter()
                    .map(|p| {
                        let q = p.local_p1;
                        [
                            q.x.to_bits(),
                            q.y.to_bits(),
                            q.z.to_bits(),
                            p.dist.to_bits(),
                        ]
                    })
                    .collect();
                (m.subshape1, m.subshape2, points)
            })
            .collect();
        out.sort();
        out
    }

    /// The gear peg sliding and rocking against the walls of its hole at 0.5 mm: at every step
    /// every contact manifold of parry's compound query (run with the same SAT) is found, with
    /// the same points to the bit, though most sub-pairs are skipped.
    #[test]
    fn skipping_never_loses_a_contact() {
        let pair = build_builtin(Builtin::Gear, 0.5e-3).expect("gear builds");
        let hole = compound_collider(&pair.hole, 0.3).build();
        let peg = compound_collider(&pair.peg, 0.3).build();
        let c_hole = hole.shape().as_composite_shape().expect("compound");
        let c_peg = peg.shape().as_composite_shape().expect("compound");
        let prediction = 30e-6;
        let (mut ours, mut ours_ws): (Manifolds, _) = (Vec::new(), None);
        let (mut parrys, mut parrys_ws): (Manifolds, _) = (Vec::new(), None);
        let steps = 600;
        let mut touching_steps = 0;
        for step in 0..steps {
            let t = step as f64 / steps as f64;
            let phase = std::f64::consts::TAU * 3.0 * t;
            // Side gap 0.25 mm: the offset swells to 0.27 mm and back, circling, with a rocking
            // tilt; the peg is free, then pressed into the walls and sliding on them.
            let offset = 0.27e-3 * (0.5 * phase).sin().powi(2);
            let peg_in_hole = Isometry3::new(
                Vector3::new(offset * phase.cos(), offset * phase.sin(), -2e-3 - 6e-3 * t),
                Vector3::new(0.2f64.to_radians() * phase.sin(), 0.0, 0.3 * t),
            );
            let pos12 = pose32(&peg_in_hole);
            compound_manifolds(&pos12, c_hole, c_peg, prediction, &mut ours, &mut ours_ws);
            contact_manifolds_composite_shape_composite_shape(
                &ExactConvexDispatcher,
                &pos12,
                c_hole,
                c_peg,
                prediction,
                &mut parrys,
                &mut parrys_ws,
            );
            let (mine, expected) = (contacts(&ours), contacts(&parrys));
            for m in &expected {
                assert!(mine.contains(m), "step {step}: lost {m:?}");
            }
            // parry's box test may drop a pair whose SAT separation is within the prediction
            // distance but whose boxes are not: such a pair is apart, never touching.
            for m in mine.iter().filter(|m| !expected.contains(m)) {
                let apart = m.2.iter().all(|p| f32::from_bits(p[3]) > 0.0);
                assert!(apart, "step {step}: extra touching {m:?}");
            }
            touching_steps += usize::from(!expected.is_empty());
        }
        assert!(
            touching_steps > steps / 4 && touching_steps < steps,
            "the path should touch and leave the walls: {touching_steps} of {steps} steps"
        );
    }
}
