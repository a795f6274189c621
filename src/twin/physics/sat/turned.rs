//! The second piece's data turned into the first piece's frame, kept across steps
//! ([`TurnedPieces`]), and its Gauss-map arcs for the edge stage's crossing test ([`GaussArcs`]).

use super::{RealEdge, SatPiece};
use rapier3d::parry::math::{Real, Rotation, Vector};
use rapier3d::parry::shape::ConvexPolyhedron;

/// The stride of the vectorised crossing test (two vectors of four f32, as the compiler unrolls
/// it): the arcs are padded to a multiple, so that none is left to the scalar remainder loop.
pub(super) const ARC_LANES: usize = 8;

/// Buffers reused across calls (one set per thread), so that a full test allocates nothing.
#[derive(Default)]
pub(super) struct Scratch {
    pub(super) crosses: Vec<bool>,
    /// B's points in A's frame.
    pub(super) pb: Vec<Vector>,
    /// The heights of B's points above A's face planes, face by face.
    pub(super) above: Vec<Real>,
}

/// Pieces turned into the frame of the pieces they are tested against: their vertices, face
/// normals and Gauss arcs, which depend on the relative rotation only. A compound's pieces are
/// placed by translation alone, so its piece pairs share that rotation at each step, and a piece of
/// the second body meets several pieces of the first: the last [`TURNED_KEPT`] turned are kept
/// and found again by the piece's id and the rotation's bits. The same operations as turning it
/// anew, so the same values to the bit.
#[derive(Clone, Default)]
pub(crate) struct TurnedPieces {
    pub(super) ring: Vec<Turned>,
    pub(super) next: usize,
}

/// Turned pieces kept (a piece of the second body meets its neighbours on the first one in
/// consecutive pairs).
pub(super) const TURNED_KEPT: usize = 16;

/// One piece turned by one rotation.
#[derive(Clone, Default)]
pub(super) struct Turned {
    pub(super) id: u32,
    pub(super) rotation: [u32; 4],
    /// The rotation times each vertex and each face normal.
    pub(super) points: Vec<Vector>,
    pub(super) normals: Vec<Vector>,
    pub(super) arcs: GaussArcs,
}

impl TurnedPieces {
    /// `b` (its id `id`) turned by `rotation`: found, or turned into the oldest entry.
    pub(super) fn find_or_turn(
        &mut self,
        b: &ConvexPolyhedron,
        sb: &SatPiece,
        id: u32,
        rotation: &Rotation,
    ) -> &Turned {
        let bits = rotation.to_array().map(f32::to_bits);
        if let Some(i) = self
            .ring
            .iter()
            .position(|t| t.id == id && t.rotation == bits)
        {
            return &self.ring[i];
        }
        let i = self.next;
        self.next = (i + 1) % TURNED_KEPT;
        if self.ring.len() <= i {
            self.ring.push(Turned::default());
        }
        let t = &mut self.ring[i];
        t.id = id;
        t.rotation = bits;
        t.points.clear();
        t.points.extend(b.points().iter().map(|&p| *rotation * p));
        t.normals.clear();
        t.normals
            .extend(b.faces().iter().map(|f| *rotation * f.normal));
        t.arcs.fill(b, sb, &t.normals, rotation);
        t
    }
}

thread_local! {
    pub(super) static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// Whether an edge of a polyhedron is a real edge: parry keeps the diagonals of its triangulated
/// faces in the edge list, with the same face on both sides (a point on the Gauss map, never a
/// separating direction). A strip piece has 15 real edges among 24.
pub(super) fn is_real(faces: [u32; 2]) -> bool {
    faces[0] != faces[1]
}

/// The real edges of the second piece on the Gauss map, in the first piece's frame, stored by
/// coordinate so that the crossing test runs over all of them at once (vectorised): per edge (in
/// the order of its [`SatPiece`]), its two adjacent face normals negated (`n1`, `n2`) and their
/// cross product, and its direction.
#[derive(Clone, Default)]
pub(super) struct GaussArcs {
    pub(super) dir: Vec<Vector>,
    pub(super) n1: [Vec<Real>; 3],
    pub(super) n2: [Vec<Real>; 3],
    pub(super) cross: [Vec<Real>; 3],
}

impl GaussArcs {
    /// Refills with the real edges of `b` (`sb`): its face normals `nb` are already in A's frame,
    /// `rotation` turns the edge directions.
    pub(super) fn fill(
        &mut self,
        b: &ConvexPolyhedron,
        sb: &SatPiece,
        nb: &[Vector],
        rotation: &Rotation,
    ) {
        for v in self
            .n1
            .iter_mut()
            .chain(&mut self.n2)
            .chain(&mut self.cross)
        {
            v.clear();
        }
        self.dir.clear();
        for e in &sb.edges {
            self.dir.push(*rotation * b.edges()[e.index as usize].dir);
            let (c, d) = (-nb[e.faces[0] as usize], -nb[e.faces[1] as usize]);
            let x = d.cross(c);
            for k in 0..3 {
                self.n1[k].push(c[k]);
                self.n2[k].push(d[k]);
                self.cross[k].push(x[k]);
            }
        }
        // Padding arcs (all zero) cross nothing; the crossing test then runs in whole vectors.
        let padded = sb.edges.len().next_multiple_of(ARC_LANES);
        for v in self
            .n1
            .iter_mut()
            .chain(&mut self.n2)
            .chain(&mut self.cross)
        {
            v.resize(padded, 0.0);
        }
    }

    /// Arcs held, the padding included.
    pub(super) fn len(&self) -> usize {
        self.n1[0].len()
    }

    /// Which arcs cross the arc of `ea`, an edge of A: the Gauss-map test of D. Gregorius
    /// (GDC 2013), without branches so that it vectorises.
    pub(super) fn crossing(&self, ea: &RealEdge, out: &mut [bool]) {
        let (fa1, fa2, w) = (ea.n1, ea.n2, ea.w);
        let m = out.len();
        let [n1x, n1y, n1z] = &self.n1;
        let [n2x, n2y, n2z] = &self.n2;
        let [cx, cy, cz] = &self.cross;
        let (n1x, n1y, n1z) = (&n1x[..m], &n1y[..m], &n1z[..m]);
        let (n2x, n2y, n2z) = (&n2x[..m], &n2y[..m], &n2z[..m]);
        let (cx, cy, cz) = (&cx[..m], &cy[..m], &cz[..m]);
        for j in 0..m {
            let cba = n1x[j] * w.x + n1y[j] * w.y + n1z[j] * w.z;
            let dba = n2x[j] * w.x + n2y[j] * w.y + n2z[j] * w.z;
            let adc = fa1.x * cx[j] + fa1.y * cy[j] + fa1.z * cz[j];
            let bdc = fa2.x * cx[j] + fa2.y * cy[j] + fa2.z * cz[j];
            out[j] = (cba * dba < 0.0) & (adc * bdc < 0.0) & (cba * bdc > 0.0);
        }
    }
}
