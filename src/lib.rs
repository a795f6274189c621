//! pegtwin: a digital twin for robotic peg-in-hole assembly of complex parts by contact-manifold
//! pose estimation (Negi et al.). The README is the user's manual; `docs/architecture.md` says
//! which file owns what.
//!
//! Four layers and a wing, each using only the ones above it in this list:
//!
//! - [`twin`]: what exists physically. Parts and meshes ([`twin::geometry`]), the robot model and
//!   its URDF loader ([`twin::robot`]), the rapier world with exact convex contacts
//!   ([`twin::physics`]), Sunrise-style impedance control ([`twin::control`]), joint-torque
//!   sensing and the wrench estimate ([`twin::sensing`]), and the work cell that steps them
//!   together behind the real robot's ports ([`twin::workcell`]).
//! - [`method`]: the paper's method, one file per stage of its Fig. 3.
//!   - sample the manifold: [`method::primitives`] (the motions) driving
//!     [`method::manifold::build`] (IV-B), stored by [`method::manifold::file`] and
//!     [`method::manifold::cache`];
//!   - observe: [`method::observe`] (IV-C), after [`method::search`] when starting above;
//!   - register: [`method::register`] (IV-D; Algorithm 1 line by line in
//!     [`method::register::algorithm1`]);
//!   - insert: [`method::insert`] (IV-E);
//!   - one trial as the sequence of those stage calls: [`method::trial`] (V-A), with its settings
//!     in [`method::config`], its random streams in [`method::seeds`], and the cell's ports in
//!     [`method::session`].
//! - [`selfcheck`], beside the method: the physics checked before a campaign is trusted, the free
//!   peg ([`selfcheck::free_peg`]), the peg on the arm ([`selfcheck::arm`]) and the stiffness the
//!   arm shows ([`selfcheck::stiffness`]).
//! - [`replay`]: see what happened. A trial recorded while it runs and played back in 3-D in one
//!   self-contained HTML page ([`replay::page`], with the viewer of `viewer/`), its meshes
//!   ([`replay::scene`]) and the registration drawn over the manifold ([`replay::registration`]).
//! - [`campaign`]: many trials. Scenario files ([`campaign::scenario`]), parallel, sharded,
//!   resumable runs ([`campaign::run`]) whose records stream from disk ([`campaign::records`]),
//!   with the replays of their failures ([`campaign::replays`]),
//!   statistics and tables ([`campaign::summary`]), figures
//!   and report.html ([`campaign::report`]), gain tuning ([`campaign::tune`]) and the regression
//!   gate ([`campaign::check`]).
//!
//! Below them all: [`pose`] (6-D poses and SE(3)), [`error`], [`choice`] (named choices),
//! [`files`], [`toml_input`] (TOML read strictly), [`figures`] (PNG and SVG), [`schedule`] (the
//! order work takes the cores, longest first). The command line lives in
//! the binary (`src/main.rs`, `src/cli/`) and only parses, calls this library and prints.

pub mod campaign;
pub mod choice;
pub mod error;
pub mod figures;
pub mod files;
pub mod method;
pub mod pose;
pub mod replay;
pub mod schedule;
pub mod selfcheck;
pub mod toml_input;
pub mod twin;
