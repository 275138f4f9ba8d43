//! The velocity step (5.1): a Tresca-type variational inequality with the known normal load
//! p_ν(u_{n−1,ν} − g) and the known friction bound s = p_τ(u_{n−1,ν} − g).
//!
//! With the nodal rule of [`crate::model::contact`], (5.1) is the minimization of
//!
//! J(v) = Σ_K ∫_K Φ(ε(v)) dx − ⟨F, v⟩ + Σ_a w_a |v_τ(a)|,   w_a = ω_a s_a,
//!
//! (Φ the potential of 𝒜, F the load of the step). Unknowns are nodal velocities, expressed in
//! the frame (ν_a, t_1, …) at contact nodes; constrained unknowns (Γ1) keep identity rows.
//!
//! **Prescribed displacement.** On a constrained unknown c (a Cartesian component of a node of
//! Γ1; contact nodes are never constrained) the velocity is given, v_c = p_c (the scheme passes
//! p_c = (u_D(t_n) − u_{n−1,c})/k, so that u_n = u_D(t_n)); the paper's u = 0 on Γ1 is p = 0.
//! The constrained unknowns are eliminated: their rows are identity rows, their columns are
//! dropped from the operator, and the coupling is moved to the right-hand side (linear 𝒜:
//! F_f − K_fc p_c; nonlinear 𝒜: the Newton iterates carry v_c = p_c and the increments vanish
//! there). The friction condensation acts on the free tangential contact unknowns only, and the
//! KKT residual is measured on the free unknowns (plus |v_c − p_c| on the constrained ones). The
//! reaction on a constrained unknown is the residual of the equilibrium there,
//! R_c = ⟨𝒜ε(v), ε(φ_c)⟩ − F_c = ∫_Γ1 σν·φ_c dΓ (the force of the support on the body).
//!
//! **Algorithm.** Proximal Newton, a generalized Newton method on the whole nonsmooth system: at
//! an iterate v_k the smooth part is replaced by a quadratic model with an SPD matrix H_k — the
//! exact tangent ∫ d𝒜(ε(v_k)) assembled at v_k ([`TangentUpdate::Newton`]), or the last
//! assembled tangent, kept while each accepted step at least halves the KKT residual
//! ([`TangentUpdate::Frozen`], the default: a linear rate, a factorization saved per
//! iteration) — and the nonsmooth model problem
//! min ½ dᵀH_k d + ⟨N(v_k) − F, d⟩ + Σ_a w_a |v_τ(a) + d_τ(a)| is condensed exactly onto the
//! tangential contact unknowns c with the Schur complement S = (E_cᵀ H_k^{-1} E_c)^{-1} and
//! solved exactly by [`crate::solvers::friction`]. It is solved in increment form (right-hand side
//! F − N(v_k), no cancellation against H_k v_k). For a linear 𝒜 the model is J itself, so one
//! iteration solves (5.1) exactly, and H, its Cholesky factor and S are computed once per run
//! and reused in every time step. With the tangential unknowns eliminated last (a supernodal
//! factor P H Pᵀ = L Lᵀ, [`crate::algebra::linalg::CholeskySolver::trailing_factor`]) a model solve is
//! ONE sparse solve split in its halves: the forward half z = L⁻¹ P b gives the condensed
//! right-hand side S (H⁻¹ b)_c = L_cc z_c, the friction forces change only the trailing block
//! of z (z_c ← z_c − L_cc⁻¹ W λ), and the backward half gives the velocity
//! (`VelocityOperator::solve_model`; two solves with a simplicial factor).
//!
//! **Merit function and stop test (nonlinear 𝒜).** The KKT residual of an iterate v is computed
//! from v alone: the multipliers are the best ones at v ([`VelocityOperator::best_multipliers`]:
//! v_τ/|v_τ| at slipping nodes, the projection onto the unit ball of the tangential force
//! imbalance at the others), so dual feasibility and complementarity hold exactly and the
//! residual r(v) is the relative stationarity of [`VelocityOperator::kkt_residual`]. The
//! iteration stops when r(v) ≤ 10⁻² × tolerance (head room under the certificate); the stop test
//! and the reported residual are the same number.
//!
//! **Globalization.** A step v + α d, tried from α = 1 by halving, is accepted when either
//! (a) r(v + αd) ≤ ½ min_{j ≤ k} r(v_j) (a new record of the residual by a fixed factor), or
//! (b) the Armijo test J(v + αd) ≤ J(v) + σ α Δ, Δ = ⟨N(v) − F, d⟩ + Σ w_a(|v_τ + d_τ| − |v_τ|)
//! < 0, holds, with J(v + αd) − J(v) summed cell by cell.
//! Why both: (b) alone stalls at round-off, because near the solution the decrease of J is
//! O(r²) and falls below the rounding error of J (≈ 1e-16 |J|) long before r reaches 1e-12:
//! every step is then rejected (observed: residuals stuck near 1e-8 to 1e-10). Test (a) measures
//! progress in the quantity that is certified and that Newton's method reduces quadratically,
//! so in the region of fast convergence full steps are taken and the residual goes to the
//! rounding level in a few iterations. Global convergence from any start: if (a) is used
//! infinitely often, the record of r tends to 0 and, J being strongly convex, the record iterates
//! converge to the solution (‖v − v*‖ ≤ C r(v)); otherwise, after the last use of (a), the
//! iteration is the Armijo-damped proximal Newton method with a positive definite model, which
//! converges globally for a strongly convex J (Lee, Sun & Saunders, SIAM J. Optim. 24, 2014).
//! When no step passes either test, the iteration is at the rounding level: the step ends with
//! its residual if that meets the certificate, else with a no-convergence error carrying the
//! residual history.
//!
//! **Layout.** `types` (settings, data and results of a step), `operator` (the operator's
//! fields and accessors), `construction` (Γ1 constraints, pattern, symbolic analysis),
//! `assembly` (H or the Newton tangent in the system frame), `factorization` (numeric factor and
//! the condensed operator S), `frames` (Cartesian ↔ system frame), `forces` (internal forces,
//! energies, friction term, reactions), `kkt` (KKT residual and best multipliers),
//! `condensation` (the model problem condensed onto Γ3 and its friction problem), `newton` (the
//! linear step with refinement and the globalized proximal Newton method) and `step` (one step:
//! checks, load, solve, contact status).

mod assembly;
mod condensation;
mod construction;
mod factorization;
mod forces;
mod frames;
mod kkt;
mod newton;
mod operator;
mod reduction;
mod step;
mod types;

pub use newton::NEWTON_HEADROOM;
pub use operator::VelocityOperator;
pub use types::{
    ImplicitNormalCompliance, TangentUpdate, VelocityData, VelocitySettings, VelocitySolution,
    VelocityStats,
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::mesh::{BoundaryPart::*, Mesh};
    use crate::fem::space::LagrangeSpace;
    use crate::model::contact::ContactNodes;
    use crate::model::laws::LinearViscosity;
    use crate::solvers::friction::FrictionSettings;
    use std::sync::Arc;

    fn operator<const D: usize>(mesh: Mesh<D>) -> VelocityOperator<D> {
        let space = Arc::new(LagrangeSpace::new(Arc::new(mesh), 1).unwrap());
        let contact = Arc::new(ContactNodes::new(&space).unwrap());
        let mut operator = VelocityOperator::new(
            space,
            Arc::new(LinearViscosity {
                shear: 1.0,
                bulk: 0.5,
            }),
            contact,
        )
        .unwrap();
        operator.factorize().unwrap();
        operator
    }

    /// The unit square clamped at x = 0, in contact at y = 0.
    fn square_with_contact(cells: [usize; 2]) -> Mesh<2> {
        Mesh::box_mesh(
            [0.0; 2],
            [1.0; 2],
            cells,
            [[Dirichlet, Neumann], [Contact, Neumann]],
        )
        .unwrap()
    }

    /// The unit cube clamped at x = 0, in contact at z = 0.
    fn cube_with_contact(cells: [usize; 3]) -> Mesh<3> {
        Mesh::box_mesh(
            [0.0; 3],
            [1.0; 3],
            cells,
            [[Dirichlet, Neumann], [Neumann, Neumann], [Contact, Neumann]],
        )
        .unwrap()
    }

    fn assert_schur_paths_agree<const D: usize>(operator: &VelocityOperator<D>) {
        let from_factor = operator
            .schur_from_trailing_factor()
            .map(|(schur, _)| schur)
            .expect("a supernodal factor with the contact unknowns last");
        let from_solves = operator.schur_from_solves().unwrap();
        let m = operator.tangential.len();
        let scale = (0..m)
            .map(|i| from_solves[(i, i)].abs())
            .fold(0.0, f64::max);
        let mut worst: f64 = 0.0;
        for i in 0..m {
            for j in 0..m {
                worst = worst.max((from_factor[(i, j)] - from_solves[(i, j)]).abs());
            }
        }
        assert!(
            worst <= 1e-10 * scale,
            "Schur complements differ by {worst:e} (scale {scale:e})"
        );
    }

    /// Both ways of solving the condensed model of (5.1), on random loads and friction bounds
    /// (stick and slip nodes, and a share `without_friction` of the nodes with none), plain and
    /// as a refinement pass: the one-solve path with the trailing factor (condensed onto the
    /// nodes with friction when they are at most half) and the two-solve path with S.
    fn assert_one_solve_path_matches_two_solves<const D: usize>(
        mut operator: VelocityOperator<D>,
        seed: u64,
        largest_bound: f64,
        without_friction: f64,
    ) {
        operator.factorize().unwrap();
        assert!(
            operator.trailing.is_some(),
            "a supernodal factor, contact last"
        );
        let mut random = crate::test_random::SeededRandom::new(seed);
        let n = operator.size();
        let m = operator.tangential.len();
        let rhs: Vec<f64> = (0..n).map(|_| random.range(-1.0, 1.0)).collect();
        let weights: Vec<f64> = (0..m / (D - 1))
            .map(|_| {
                let bound = random.range(0.0, largest_bound);
                if random.range(0.0, 1.0) < without_friction {
                    0.0
                } else {
                    bound
                }
            })
            .collect();
        operator.prepare_condensation(&weights).unwrap();
        let with_friction = weights.iter().filter(|&&w| w > 0.0).count();
        assert_eq!(
            operator.reduction.is_some(),
            2 * with_friction <= weights.len(),
            "condensed onto the nodes with friction exactly when they are at most half"
        );
        assert!(without_friction < 0.5 || operator.reduction.is_some());
        if let Some(reduction) = &operator.reduction {
            // made for these nodes only
            assert!(reduction.matches(&weights));
            let mut other = weights.clone();
            let free = other.iter().position(|&w| w == 0.0).unwrap();
            other[free] = 1.0;
            assert!(!reduction.matches(&other));
        }
        // the two-solve path condenses onto all of Γ3 with S
        operator.ensure_schur().unwrap();
        let base: Vec<f64> = (0..n).map(|_| random.range(-0.1, 0.1)).collect();
        let settings = FrictionSettings::default();
        for base in [None, Some(base.as_slice())] {
            let solve = |operator: &VelocityOperator<D>| {
                let mut multipliers = vec![0.0; m];
                let mut stats = VelocityStats::default();
                let velocity = operator
                    .solve_model(
                        &rhs,
                        &weights,
                        &vec![0.0; n],
                        base,
                        &mut multipliers,
                        &settings,
                        &mut stats,
                    )
                    .unwrap();
                (velocity, multipliers)
            };
            let (one, one_multipliers) = solve(&operator);
            let trailing = operator.trailing.take();
            let (two, two_multipliers) = solve(&operator);
            operator.trailing = trailing;
            let scale = two.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let worst = one
                .iter()
                .zip(&two)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                worst <= 1e-10 * scale,
                "velocities differ by {worst:e} of {scale:e}"
            );
            let stuck = two_multipliers
                .chunks(D - 1)
                .zip(&weights)
                .filter(|(l, w)| {
                    l.iter().map(|x| x * x).sum::<f64>().sqrt() < 1.0 - 1e-6 || **w == 0.0
                })
                .count();
            assert!(
                stuck > 0 && stuck < weights.len(),
                "stick and slip nodes: {stuck}"
            );
            for (a, b) in one_multipliers.iter().zip(&two_multipliers) {
                assert!((a - b).abs() <= 1e-8, "multipliers {a} vs {b}");
            }
        }
    }

    #[test]
    fn one_solve_velocity_step_matches_two_solves_2d() {
        let mesh = square_with_contact([96, 48]);
        assert_one_solve_path_matches_two_solves(operator(mesh), 7, 0.5, 0.0);
    }

    #[test]
    fn one_solve_velocity_step_matches_two_solves_3d() {
        let mesh = cube_with_contact([6; 3]);
        assert_one_solve_path_matches_two_solves(operator(mesh), 11, 20.0, 0.0);
    }

    #[test]
    fn velocity_step_condensed_onto_the_nodes_with_friction_matches_two_solves_2d() {
        let mesh = square_with_contact([96, 48]);
        assert_one_solve_path_matches_two_solves(operator(mesh), 13, 0.5, 0.7);
    }

    #[test]
    fn velocity_step_condensed_onto_the_nodes_with_friction_matches_two_solves_3d() {
        let mesh = cube_with_contact([6; 3]);
        assert_one_solve_path_matches_two_solves(operator(mesh), 17, 20.0, 0.7);
    }

    #[test]
    fn schur_complement_from_trailing_factor_matches_solves_2d() {
        let mesh = square_with_contact([128, 128]);
        assert_schur_paths_agree(&operator(mesh));
    }

    #[test]
    fn schur_complement_from_trailing_factor_matches_solves_3d() {
        let mesh = cube_with_contact([8; 3]);
        assert_schur_paths_agree(&operator(mesh));
    }

    #[test]
    fn frictionless_operator_refuses_a_positive_friction_bound_naming_the_node() {
        let mut operator = operator(square_with_contact([4, 4]));
        operator.without_friction().unwrap();
        assert!(operator.tangential.is_empty());
        let refusal = operator
            .arrange_contact(true, false)
            .unwrap_err()
            .to_string();
        assert!(refusal.contains("cannot be restored"), "{refusal}");
        let contact = operator.contact().clone();
        let n = operator.size();
        let mut bound = vec![0.0; contact.len()];
        bound[1] = 0.5;
        let data = VelocityData {
            load: &vec![0.0; n],
            normal_pressure: &vec![0.0; contact.len()],
            friction_bound: &bound,
            implicit_contact: None,
            prescribed: None,
        };
        let message = operator
            .solve(&data, &vec![0.0; n], &VelocitySettings::default())
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("built without friction")
                && message.contains(&format!("contact node {}", contact.nodes[1])),
            "{message}"
        );
        // zero bounds solve
        let zero = vec![0.0; contact.len()];
        let data = VelocityData {
            friction_bound: &zero,
            ..data
        };
        let solution = operator
            .solve(&data, &vec![0.0; n], &VelocitySettings::default())
            .unwrap();
        assert!(solution.stats.kkt_residual <= 1e-10);
    }
}
