//! Finite elements for the quasistatic viscoelastic contact problem with normal compliance,
//! Coulomb friction and damage of W. Han, M. Shillor, M. Sofonea, *Variational and numerical
//! analysis of a quasistatic viscoelastic problem with normal compliance, friction and damage*,
//! J. Comput. Appl. Math. 137 (2001) 377–398.
//!
//! The crate implements the fully discrete scheme P_V^hk (5.1)–(5.5): continuous P1 or P2
//! elements on triangles and tetrahedra, backward Euler in time, the velocity step (5.1) solved
//! exactly as a Tresca-type variational inequality, and the damage step (5.2) solved exactly as
//! a box-constrained quadratic program.
//!
//! The folders follow the paper:
//! - [`model`]: Problem P of §2–3 — constitutive laws, load fields, the contact boundary Γ3,
//!   Dirichlet data on Γ1;
//! - [`fem`]: the finite elements of §5 — meshes, refinement, shape regularity, quadrature,
//!   Lagrange elements, the spaces X^h;
//! - [`algebra`]: sparse Cholesky (symbolic once, numeric many times), triangular solves,
//!   orderings, algebraic multigrid, memory estimates;
//! - [`solvers`]: the exact solvers of the friction problem of (5.1) and the box QP of (5.2);
//! - [`scheme`]: the scheme P_V^hk (5.1)–(5.5) — the velocity step, the damage step, the
//!   element kernels and load vectors, the step limit of the explicit terms, and [`Simulation`];
//! - [`io`]: Gmsh meshes in, ParaView files out, the atomic writer.
//!
//! ```
//! use contact_damage::model::laws::{DamagedHooke, LinearViscosity, NormalComplianceCoulomb, TruncatedFremond};
//! use contact_damage::fem::mesh::{BoundaryPart::*, Mesh};
//! use contact_damage::scheme::{Data, Model, Problem, SchemeSettings, Simulation};
//! use std::sync::Arc;
//!
//! // unit square, clamped at x = 0, foundation below y = 0, traction-free elsewhere
//! let mesh = Mesh::box_mesh([0.0, 0.0], [1.0, 1.0], [8, 8], [[Dirichlet, Neumann], [Contact, Neumann]])?;
//! let model = Model {
//!     viscosity: Arc::new(LinearViscosity { shear: 1.0, bulk: 0.5 }),
//!     elasticity: Arc::new(DamagedHooke { shear_modulus: 1.0, lame_lambda: 1.0 }),
//!     damage_source: Arc::new(TruncatedFremond { lambda_d: 0.1, lambda_w: 0.05, damage_floor: 0.1, strain_energy_cap: 10.0 }),
//!     contact: Arc::new(NormalComplianceCoulomb { stiffness: 10.0, friction: 0.4, wear: 0.0 }),
//!     damage_diffusion: 0.1,
//! };
//! let data = Data {
//!     // the top side is pressed down and pulled sideways
//!     traction: Some(Arc::new(|x: &[f64; 2], t: f64, _normal: &[f64; 2]| {
//!         if x[1] > 1.0 - 1e-12 { [0.3 * t, -0.5] } else { [0.0, 0.0] }
//!     })),
//!     body_force: None,
//!     body_stress: None,
//!     contact_traction: None,
//!     damage_supply: None,
//!     damage_flux: None,
//!     gap: Arc::new(|_, _| 0.0),
//!     dirichlet: Vec::new(),
//!     initial_displacement: Arc::new(|_| [0.0, 0.0]),
//!     initial_damage: Arc::new(|_| 1.0),
//!     jump_planes: Vec::new(),
//! };
//! let problem = Problem { mesh: Arc::new(mesh), degree: 1, model, data, final_time: 1.0, steps: 10, settings: SchemeSettings::default() };
//! let mut simulation = Simulation::new(problem)?;
//! let summary = simulation.run(|report| {
//!     // every step is solved exactly: KKT residuals far below the discretization error
//!     assert!(report.velocity_stats.kkt_residual <= 1e-10 && report.damage_stats.kkt_residual <= 1e-12);
//!     Ok(())
//! })?;
//! assert_eq!(summary.steps, 10);
//! assert!(summary.steps_with_status.stick + summary.steps_with_status.slip > 0, "the body touches the foundation");
//! # Ok::<(), contact_damage::Error>(())
//! ```

pub mod algebra;
pub mod error;
pub mod fem;
pub mod io;
pub mod model;
pub mod scheme;
pub mod solvers;
#[cfg(test)]
mod test_random;

pub use error::{Error, Result};
pub use fem::mesh::{BoundaryPart, Mesh};
pub use fem::space::LagrangeSpace;
pub use scheme::{
    ContactTreatment, DamageEvolution, Data, Model, Problem, RunSummary, SchemeSettings,
    Simulation, State, StatusCounts, StepOutcome, StepReport,
};

/// The code blocks of the README run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;
