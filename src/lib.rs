//! pegtwin: a digital twin for robotic peg-in-hole assembly of complex parts by contact-manifold
//! pose estimation (Negi et al.). See README.md for the pipeline and the commands.

pub mod campaign;
pub mod error;
pub mod files;
pub mod method;
pub mod pose;
pub mod twin;
