//! How a printed pair came out of the printer (paper IV-B: the parts are FDM-printed PLA;
//! docs/physics.md, "The real cell"): its walls stand off the CAD (outsides print large, holes
//! small) and its edges round. A pair is printed once: its reference manifold and every trial of
//! it use the same print. Still exact convex pieces: the print is an offset of the profile and a
//! bevel of another size, not a penalty term.

use serde::{Deserialize, Serialize};

/// One print of a pair.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Print {
    /// How far each wall of the peg stands out of its CAD, m (per side; negative: inside it).
    pub peg_growth_m: f64,
    /// How far each wall of the hole stands into the cavity, m (per side; negative: back from it).
    pub hole_shrink_m: f64,
    /// The peg tip's edge, as a 45-degree bevel of this size, m (the CAD's chamfer and the print's
    /// rounding together).
    pub peg_edge_m: f64,
    /// The hole mouth's edge, as the peg's, m.
    pub hole_edge_m: f64,
    /// The printed pair's diametral clearance, m: what calipers would measure (the nominal one
    /// less twice the growth and the shrink).
    pub clearance_m: f64,
}

impl Print {
    /// The pair as its CAD says (the ideal cell's, and an assembly's, whose meshes are the parts).
    pub fn exact(clearance_m: f64) -> Self {
        Print {
            peg_growth_m: 0.0,
            hole_shrink_m: 0.0,
            peg_edge_m: super::PEG_TIP_CHAMFER_M,
            hole_edge_m: super::HOLE_ENTRY_CHAMFER_M,
            clearance_m,
        }
    }

    /// The print of a pair of nominal clearance `clearance_m` with these deviations.
    pub fn new(clearance_m: f64, growth_m: f64, shrink_m: f64, edges_m: [f64; 2]) -> Self {
        Print {
            peg_growth_m: growth_m,
            hole_shrink_m: shrink_m,
            peg_edge_m: edges_m[0],
            hole_edge_m: edges_m[1],
            clearance_m: clearance_m - 2.0 * (growth_m + shrink_m),
        }
    }

    /// A short key of the print for cache file names: its deviations in whole nanometres.
    pub fn key(&self) -> String {
        let nm = |v: f64| (v * 1e9).round() as i64;
        format!(
            "print{}_{}_{}_{}",
            nm(self.peg_growth_m),
            nm(self.hole_shrink_m),
            nm(self.peg_edge_m),
            nm(self.hole_edge_m)
        )
    }
}
