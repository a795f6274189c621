//! Contact manifolds between two compounds of convex pieces (a peg and its hole block), with a
//! Verlet candidate list and motion-bounded skipping of pieces proven apart.
//!
//! parry's compound-compound query walks both trees at every step, looks every sub-pair up in a
//! hash map and copies each sub-pair's manifold (with its boxed sub-shape poses) into a new list:
//! a `gear` peg in its hole at 0.5 mm has about 850 sub-pairs within reach per step, nearly all of
//! them apart. Here:
//!
//! 1. The candidates are the sub-pairs whose boxes, loosened by the prediction distance plus
//!    [`VERLET_MARGIN_M`], overlap. The list is rebuilt only when the two bodies may have moved
//!    relative to each other by more than the margin (the Verlet neighbour list of molecular
//!    dynamics codes).
//! 2. A sub-pair proven apart by a gap `g` (a separating axis of the SAT) is not tested again
//!    until the relative motion since could have closed `g` down to the prediction distance. Any
//!    point of body 2 at distance `r` from its origin moves relative to body 1 in a step by at
//!    most `|dt| + 2 sin(dtheta / 2) r` (and symmetrically); these bounds are summed as the
//!    bodies move (`Odometer`), so a skipped pair is provably farther apart than the
//!    prediction distance: no contact is lost.
//! 3. Only the manifolds that hold contact points are handed to rapier; they come back at the
//!    next step with the solver's impulses (warm start) and return to their slot.
//!
//! Everything runs in a fixed order (candidates sorted by piece indices), so results do not
//! depend on anything but the inputs.

use super::sat::{SatPiece, TurnedPieces, sat_manifold};
use rapier3d::parry::bounding_volume::{Aabb, BoundingVolume};
use rapier3d::parry::math::{Pose, Real, Rotation, Vector};
use rapier3d::parry::query::details::{TypedWorkspaceData, WorkspaceData};
use rapier3d::parry::query::{
    ContactManifold, ContactManifoldsWorkspace, DefaultQueryDispatcher, PersistentQueryDispatcher,
};
use rapier3d::parry::shape::CompositeShape;
use rapier3d::parry::utils::PoseOpt;

/// How much farther than the prediction distance the candidate list reaches, metres. Larger
/// means fewer rebuilds and more candidates to bound each step.
pub const VERLET_MARGIN_M: Real = 0.5e-3;

/// The relative pose of the two bodies at one instant, in the form the travel bound needs.
#[derive(Clone, Copy)]
struct Snapshot {
    rotation: Rotation,
    /// Origin of body 2 in body 1's frame, and of body 1 in body 2's frame, metres.
    t12: Vector,
    t21: Vector,
}

impl Snapshot {
    /// From the relative pose and its inverse.
    fn of(pos12: &Pose, pos21: &Pose) -> Self {
        Snapshot {
            rotation: pos12.rotation,
            t12: pos12.translation,
            t21: pos21.translation,
        }
    }

    /// Upper bound (metres) on how far a point at distance `r1` from body 1's origin, or `r2`
    /// from body 2's, has moved relative to the other body between `self` and `now`:
    /// `|(R' - R) p + dt| <= 2 sin(dtheta / 2) |p| + |dt|`, from whichever body gives less.
    fn travel(&self, now: &Snapshot, r1: Real, r2: Real) -> Real {
        let chord = 2.0 * (now.rotation * self.rotation.inverse()).xyz().length();
        let seen_from_1 = (now.t12 - self.t12).length() + chord * r2;
        let seen_from_2 = (now.t21 - self.t21).length() + chord * r1;
        seen_from_1.min(seen_from_2)
    }
}

/// Running sums of the per-step motion bounds since the workspace began: a point at `r` from
/// body 2's origin has moved relative to body 1 by at most `t12 + chord r` in all (the triangle
/// inequality over its path), and symmetrically. Comparing two readings costs a few flops where
/// [`Snapshot::travel`] costs a quaternion product and three square roots.
#[derive(Clone, Copy, Default)]
struct Odometer {
    /// Path lengths of body 2's origin in body 1's frame and of body 1's in body 2's, metres.
    t12: f64,
    t21: f64,
    /// Sum of the per-step chords 2 sin(dtheta / 2), metres per metre of radius.
    chord: f64,
}

impl Odometer {
    fn advance(&mut self, from: &Snapshot, to: &Snapshot) {
        self.t12 += f64::from((to.t12 - from.t12).length());
        self.t21 += f64::from((to.t21 - from.t21).length());
        self.chord += f64::from(2.0 * (to.rotation * from.rotation.inverse()).xyz().length());
    }

    /// Upper bound (metres) on the relative motion of a point at `r1` from body 1's origin, or
    /// `r2` from body 2's, between the reading `then` and `self`.
    fn travel_since(&self, then: &Odometer, r1: Real, r2: Real) -> f64 {
        let chord = self.chord - then.chord;
        let seen_from_1 = self.t12 - then.t12 + chord * f64::from(r2);
        let seen_from_2 = self.t21 - then.t21 + chord * f64::from(r1);
        seen_from_1.min(seen_from_2)
    }
}

/// One candidate sub-pair and its persistent manifold.
#[derive(Clone)]
struct Slot<M, C> {
    leaf1: u32,
    leaf2: u32,
    /// Largest distance of a point of each piece from its body's origin, metres.
    r1: Real,
    r2: Real,
    /// Proven gap between the pieces at the odometer reading `checked`, metres (0 when touching
    /// or unknown).
    gap: Real,
    checked: Odometer,
    manifold: ContactManifold<M, C>,
}

/// The state kept between steps for one pair of compound colliders.
#[derive(Clone)]
struct Workspace<M, C> {
    /// Sorted by (leaf1, leaf2).
    slots: Vec<Slot<M, C>>,
    /// When the list was built and how far it reaches (metres).
    anchor: Option<(Snapshot, Real)>,
    /// The relative pose at the last call, and the motion bounds summed over all calls.
    last: Option<Snapshot>,
    odometer: Odometer,
    /// Slots whose manifolds are with rapier, in the order handed over.
    lent: Vec<usize>,
    /// Per leaf of each body, what is kept of it once known.
    leaves1: Vec<Option<Leaf>>,
    leaves2: Vec<Option<Leaf>>,
    /// Pieces of body 2 turned into the frames of body 1's pieces, by leaf.
    turned: TurnedPieces,
}

/// What is kept of a piece of a compound.
#[derive(Clone)]
struct Leaf {
    /// Its largest distance from the body's origin, metres.
    radius: Real,
    /// Its data for the separating-axis test, when it is a convex polyhedron.
    sat: Option<SatPiece>,
}

impl<M, C> Default for Workspace<M, C> {
    fn default() -> Self {
        Workspace {
            slots: Vec::new(),
            anchor: None,
            last: None,
            odometer: Odometer::default(),
            lent: Vec::new(),
            leaves1: Vec::new(),
            leaves2: Vec::new(),
            turned: TurnedPieces::default(),
        }
    }
}

impl<M, C> WorkspaceData for Workspace<M, C>
where
    M: Clone + Send + Sync + 'static,
    C: Clone + Send + Sync + 'static,
{
    fn as_typed_workspace_data(&self) -> TypedWorkspaceData<'_> {
        TypedWorkspaceData::Custom
    }

    fn clone_dyn(&self) -> Box<dyn WorkspaceData> {
        Box::new(self.clone())
    }
}

/// Contact manifolds between two compounds (`pos12` places compound 2 in compound 1's frame):
/// the replacement for parry's `contact_manifolds_composite_shape_composite_shape`.
pub fn compound_manifolds<M, C>(
    pos12: &Pose,
    c1: &dyn CompositeShape,
    c2: &dyn CompositeShape,
    prediction: Real,
    manifolds: &mut Vec<ContactManifold<M, C>>,
    workspace: &mut Option<ContactManifoldsWorkspace>,
) where
    M: Default + Clone + Send + Sync + 'static,
    C: Default + Copy + Send + Sync + 'static,
    DefaultQueryDispatcher: PersistentQueryDispatcher<M, C>,
{
    let fresh = workspace
        .as_ref()
        .is_none_or(|w| !w.0.is::<Workspace<M, C>>());
    if fresh {
        *workspace = Some(ContactManifoldsWorkspace(Box::new(
            Workspace::<M, C>::default(),
        )));
    }
    let Some(ws) = workspace
        .as_mut()
        .and_then(|w| w.0.downcast_mut::<Workspace<M, C>>())
    else {
        return;
    };
    ws.take_back(manifolds);
    let pos21 = pos12.inverse();
    let now = Snapshot::of(pos12, &pos21);
    if let Some(last) = ws.last {
        ws.odometer.advance(&last, &now);
    }
    ws.last = Some(now);
    if ws.needs_rebuild(c1, c2, &now, prediction) {
        ws.rebuild(c1, c2, pos12, prediction, now);
    }
    let odometer = ws.odometer;
    for slot in &mut ws.slots {
        let bound = odometer.travel_since(&slot.checked, slot.r1, slot.r2);
        if f64::from(slot.gap - prediction) > bound {
            continue;
        }
        let pieces = (
            sat_of(&ws.leaves1, slot.leaf1),
            sat_of(&ws.leaves2, slot.leaf2),
        );
        slot.gap =
            piece_pair(&pos21, (c1, c2), pieces, slot, prediction, &mut ws.turned).unwrap_or(0.0);
        slot.checked = odometer;
    }
    ws.lend(manifolds);
}

/// Tests one sub-pair (`pos21` places compound 1 in compound 2's frame; `pieces` are its pieces'
/// SAT data, where they are convex polyhedra); `Some(gap)` when its pieces are proven apart (see
/// [`sat_manifold`]).
fn piece_pair<M, C>(
    pos21: &Pose,
    (c1, c2): (&dyn CompositeShape, &dyn CompositeShape),
    pieces: (Option<&SatPiece>, Option<&SatPiece>),
    slot: &mut Slot<M, C>,
    prediction: Real,
    turned: &mut TurnedPieces,
) -> Option<Real>
where
    M: Default + Clone,
    C: Default + Copy,
    DefaultQueryDispatcher: PersistentQueryDispatcher<M, C>,
{
    let mut gap = None;
    let manifold = &mut slot.manifold;
    c1.map_part_at(slot.leaf1, &mut |part1, shape1, normals1| {
        c2.map_part_at(slot.leaf2, &mut |part2, shape2, normals2| {
            // Piece 2 in piece 1's frame, (part2⁻¹ · pos21 · part1)⁻¹, composed as parry does.
            let pos = part2.inv_mul(&part1.prepend_to(pos21)).inverse();
            let polyhedra = (shape1.as_convex_polyhedron(), shape2.as_convex_polyhedron());
            gap = match (polyhedra, pieces) {
                ((Some(a), Some(b)), (Some(sa), Some(sb))) => {
                    let b = (b, sb, slot.leaf2);
                    sat_manifold(&pos, (a, sa), b, prediction, manifold, turned)
                }
                _ => {
                    let _ = DefaultQueryDispatcher.contact_manifold_convex_convex(
                        &pos, shape1, shape2, normals1, normals2, prediction, manifold,
                    );
                    None
                }
            };
        });
    });
    gap
}

impl<M, C> Workspace<M, C>
where
    M: Default + Clone,
    C: Default + Copy,
{
    /// Puts the manifolds lent to rapier at the last step (now holding the solver's impulses)
    /// back in their slots. If rapier dropped or changed them, the list starts over.
    fn take_back(&mut self, manifolds: &mut Vec<ContactManifold<M, C>>) {
        let intact = manifolds.len() == self.lent.len()
            && manifolds.iter().zip(&self.lent).all(|(m, &i)| {
                self.slots
                    .get(i)
                    .is_some_and(|s| (s.leaf1, s.leaf2) == (m.subshape1, m.subshape2))
            });
        if intact {
            for (m, &i) in manifolds.drain(..).zip(&self.lent) {
                self.slots[i].manifold = m;
            }
        } else {
            manifolds.clear();
            self.slots.clear();
            self.anchor = None;
        }
        self.lent.clear();
    }

    /// Hands rapier the manifolds that hold contact points, in slot order.
    fn lend(&mut self, manifolds: &mut Vec<ContactManifold<M, C>>) {
        for (i, slot) in self.slots.iter_mut().enumerate() {
            if !slot.manifold.points.is_empty() {
                self.lent.push(i);
                manifolds.push(std::mem::take(&mut slot.manifold));
            }
        }
    }

    /// Whether a sub-pair within `prediction` now could be missing from the list: the bodies
    /// may have moved relative to each other by more than the list's reach minus `prediction`.
    fn needs_rebuild(
        &self,
        c1: &dyn CompositeShape,
        c2: &dyn CompositeShape,
        now: &Snapshot,
        prediction: Real,
    ) -> bool {
        let Some((anchor, reach)) = self.anchor else {
            return true;
        };
        let r1 = body_radius(c1);
        let r2 = body_radius(c2);
        prediction + anchor.travel(now, r1, r2) > reach
    }

    /// Rebuilds the candidate list at `pos12`, keeping the slots (and manifolds) of the
    /// sub-pairs still in it.
    fn rebuild(
        &mut self,
        c1: &dyn CompositeShape,
        c2: &dyn CompositeShape,
        pos12: &Pose,
        prediction: Real,
        now: Snapshot,
    ) {
        let reach = prediction + VERLET_MARGIN_M;
        let keys = candidates(c1, c2, pos12, reach);
        let mut old = std::mem::take(&mut self.slots).into_iter().peekable();
        let mut slots = Vec::with_capacity(keys.len());
        for (leaf1, leaf2) in keys {
            while old
                .peek()
                .is_some_and(|s| (s.leaf1, s.leaf2) < (leaf1, leaf2))
            {
                old.next();
            }
            let slot = match old.next_if(|s| (s.leaf1, s.leaf2) == (leaf1, leaf2)) {
                Some(s) => s,
                None => Slot {
                    leaf1,
                    leaf2,
                    r1: leaf(&mut self.leaves1, c1, leaf1).radius,
                    r2: leaf(&mut self.leaves2, c2, leaf2).radius,
                    gap: 0.0,
                    checked: self.odometer,
                    manifold: new_manifold(c1, c2, leaf1, leaf2),
                },
            };
            slots.push(slot);
        }
        self.slots = slots;
        self.anchor = Some((now, reach));
    }
}

/// The sub-pairs whose boxes, loosened by `reach`, overlap at `pos12`; sorted.
fn candidates(
    c1: &dyn CompositeShape,
    c2: &dyn CompositeShape,
    pos12: &Pose,
    reach: Real,
) -> Vec<(u32, u32)> {
    let pos21 = pos12.inverse();
    let root2 = c2.bvh().root_aabb().transform_by(pos12).loosened(reach);
    let mut keys = Vec::new();
    for leaf1 in c1.bvh().intersect_aabb(&root2) {
        c1.map_part_at(leaf1, &mut |part1, shape1, _| {
            let box1: Aabb = shape1
                .compute_aabb(&part1.prepend_to(&pos21))
                .loosened(reach);
            keys.extend(c2.bvh().intersect_aabb(&box1).map(|leaf2| (leaf1, leaf2)));
        });
    }
    keys.sort_unstable();
    keys.dedup();
    keys
}

/// An empty manifold for a sub-pair, with the pieces' ids and poses as rapier expects them.
fn new_manifold<M: Default, C: Default + Copy>(
    c1: &dyn CompositeShape,
    c2: &dyn CompositeShape,
    leaf1: u32,
    leaf2: u32,
) -> ContactManifold<M, C> {
    let mut m = ContactManifold::new();
    m.subshape1 = leaf1;
    m.subshape2 = leaf2;
    c1.map_part_at(leaf1, &mut |part, _, _| m.set_subshape_pos1(part.copied()));
    c2.map_part_at(leaf2, &mut |part, _, _| m.set_subshape_pos2(part.copied()));
    m
}

/// Largest distance from the origin of a point of `aabb`, metres.
fn corner_radius(aabb: &Aabb) -> Real {
    aabb.mins.abs().max(aabb.maxs.abs()).length()
}

/// Largest distance of a point of the compound from its origin (its root box), metres.
fn body_radius(c: &dyn CompositeShape) -> Real {
    corner_radius(&c.bvh().root_aabb())
}

/// The SAT data of a piece already met.
fn sat_of(leaves: &[Option<Leaf>], leaf: u32) -> Option<&SatPiece> {
    leaves[leaf as usize].as_ref().and_then(|l| l.sat.as_ref())
}

/// What is kept of one piece of a compound (its largest distance from the compound's origin and
/// its SAT data), computed at first use.
fn leaf<'a>(cache: &'a mut Vec<Option<Leaf>>, c: &dyn CompositeShape, leaf: u32) -> &'a Leaf {
    let i = leaf as usize;
    if cache.len() <= i {
        cache.resize(i + 1, None);
    }
    cache[i].get_or_insert_with(|| {
        let mut out = Leaf {
            radius: 0.0,
            sat: None,
        };
        c.map_part_at(leaf, &mut |part, shape, _| {
            let pose = part.copied().unwrap_or(Pose::IDENTITY);
            out.radius = corner_radius(&shape.compute_aabb(&pose));
            out.sat = shape.as_convex_polyhedron().map(SatPiece::new);
        });
        out
    })
}
