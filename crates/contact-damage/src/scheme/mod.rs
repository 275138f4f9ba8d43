//! The fully discrete scheme, Problem P_V^hk (5.1)–(5.5): for n = 1, …, N, given u_{n−1} and
//! β_{n−1}, solve the velocity step (5.1) and the damage step (5.2) — concurrently, since both
//! depend only on step n−1 — then update u_n = u_{n−1} + k v_n (5.4)–(5.5). Initial data are
//! interpolated, u_0 = Π^h u0, β_0 = Π^h β0 (5.3), (5.30).

pub mod assembly;
pub mod damage;
pub mod loads;
pub mod stability;
pub mod state;
pub mod velocity;

use crate::error::{Error, Result};
use crate::fem::mesh::Mesh;
use crate::fem::space::{FacetRule, LagrangeSpace};
use crate::model::contact::{ContactNodes, ContactStatus};
use crate::model::dirichlet::DirichletConstraints;
pub use crate::model::dirichlet::PrescribedDisplacement;
use crate::model::rigid::check_rigid_motions;
use crate::scheme::assembly::FacetPoints;
pub use crate::scheme::damage::BoundSetPrediction;
use crate::scheme::damage::{DamageOperator, DamageSolution};
use crate::scheme::loads::{BulkData, LoadQuadrature};
use crate::scheme::stability::{step_limit, StepLimit};
use crate::scheme::velocity::{
    ImplicitNormalCompliance, VelocityData, VelocityOperator, VelocitySettings, VelocitySolution,
    VelocityStats,
};
use crate::solvers::box_qp::{BoxQpSettings, BoxQpStats};
use nalgebra::SVector;
use std::sync::Arc;

pub use crate::model::fields::{
    BoundaryScalarField, BoundaryVectorField, PointBoundaryVectorField, PointScalarField,
    ScalarField, StaticScalarField, StaticVectorField, VectorField,
};
pub use crate::model::problem::{Data, JumpPlane, Model};
pub use state::State;
/// Solver settings of both steps.
#[derive(Debug, Clone, Copy, Default)]
pub struct SchemeSettings {
    /// Velocity step (5.1).
    pub velocity: VelocitySettings,
    /// Damage step (5.2).
    pub damage: BoxQpSettings,
    /// How the damage step predicts its bound sets.
    pub damage_bound_sets: BoundSetPrediction,
    /// Where the normal compliance of the velocity step is evaluated.
    pub contact: ContactTreatment,
    /// Whether the damage evolves by (5.2) or stays at β_0.
    pub damage_evolution: DamageEvolution,
}

/// Whether the damage step (5.2) is solved.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum DamageEvolution {
    /// β_n from the damage step (5.2) (the paper's model, the default).
    #[default]
    Parabolic,
    /// β_n = β_0 for every n and no damage step: a pure contact problem (with β_0 = 1, the
    /// viscoelastic body of §2 without damage). The damage laws are not used.
    Frozen,
}

/// Where the velocity step takes the normal compliance p_ν.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum ContactTreatment {
    /// At u_{n−1}, as in the paper's scheme (5.1) (the default, verified against Theorem 5.2).
    /// Stable only while k c_ν is small against the viscous stiffness.
    #[default]
    Explicit,
    /// At u_n = u_{n−1} + k v_n (the friction bound stays at u_{n−1}): a strongly monotone step
    /// solved exactly by generalized Newton, stable for any k (stiff contact). The normal
    /// compliance takes the gap at t_n, p_ν(u_{n,ν} − g(t_n)); the friction bound stays
    /// p_τ(u_{n−1,ν} − g(t_{n−1})).
    Implicit,
}

/// Problem P_V^hk: mesh, degree l, model, data, T and N.
#[derive(Clone)]
pub struct Problem<const D: usize> {
    /// The mesh 𝒯^h.
    pub mesh: Arc<Mesh<D>>,
    /// Polynomial degree l ∈ {1, 2} of X^h.
    pub degree: usize,
    /// Constitutive laws.
    pub model: Model<D>,
    /// Loads and initial data.
    pub data: Data<D>,
    /// Final time T > 0.
    pub final_time: f64,
    /// Number of time steps N ≥ 1 (k = T/N).
    pub steps: usize,
    /// Solver settings.
    pub settings: SchemeSettings,
}

/// What one step of the scheme computed ([`Simulation::step`]).
#[derive(Debug, Clone)]
pub struct StepOutcome {
    /// The velocity step (5.1): v_n, contact status, friction multipliers, reactions, statistics.
    pub velocity: VelocitySolution,
    /// The damage step (5.2): β_n and the statistics of the box QP.
    pub damage: DamageSolution,
    /// p_ν per contact node as used in the step (at u_{n−1}, or at u_n when implicit).
    pub normal_pressure: Vec<f64>,
    /// The friction bound p_τ per contact node (at u_{n−1}).
    pub friction_bound: Vec<f64>,
}

/// Counts of something per contact status: separated, stick, slip.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StatusCounts {
    /// Separated (p_ν = 0).
    pub separated: usize,
    /// In contact and sticking.
    pub stick: usize,
    /// In contact and slipping.
    pub slip: usize,
}

/// What the observer sees after each step.
pub struct StepReport<'a, const D: usize> {
    /// The state after the step.
    pub state: &'a State,
    /// The finite element space of every field.
    pub space: &'a LagrangeSpace<D>,
    /// The contact nodes (order of `contact_status` and `multipliers`).
    pub contact: &'a ContactNodes<D>,
    /// Status of each contact node in the velocity step.
    pub contact_status: &'a [ContactStatus],
    /// Normal pressure p_ν per contact node used in the step.
    pub normal_pressure: &'a [f64],
    /// Friction bound p_τ per contact node used in the step.
    pub friction_bound: &'a [f64],
    /// Friction multipliers (D−1 per contact node).
    pub multipliers: &'a [f64],
    /// Resultant reaction ∫ σν dΓ of each part of Γ1 (order of
    /// [`Simulation::dirichlet_parts`]): the force of the support on the body.
    pub reactions: &'a [[f64; D]],
    /// Velocity step statistics.
    pub velocity_stats: &'a VelocityStats,
    /// Damage step statistics.
    pub damage_stats: &'a BoxQpStats,
}

/// Totals over a run.
#[derive(Debug, Clone, Default)]
pub struct RunSummary {
    /// Steps done.
    pub steps: usize,
    /// Largest KKT residual of a velocity step.
    pub max_velocity_kkt: f64,
    /// Largest KKT residual of a damage step.
    pub max_damage_kkt: f64,
    /// Newton iterations of all velocity steps.
    pub velocity_newton_iterations: usize,
    /// Largest number of Newton iterations of one velocity step.
    pub max_velocity_newton_iterations: usize,
    /// The KKT residual history of the velocity step that took the most Newton iterations
    /// (the first such step).
    pub slowest_velocity_history: Vec<f64>,
    /// Semismooth Newton iterations of the friction problems.
    pub friction_iterations: usize,
    /// Active-set iterations of all damage steps.
    pub damage_iterations: usize,
    /// Numeric factorizations of the velocity operator.
    pub velocity_factorizations: usize,
    /// Numeric factorizations in the damage steps.
    pub damage_factorizations: usize,
    /// Steps in which some contact node was in each state.
    pub steps_with_status: StatusCounts,
    /// Steps in which the lower bound β = 0 was active at some node.
    pub steps_with_lower_damage_bound: usize,
    /// Steps in which the upper bound β = 1 was active at some node.
    pub steps_with_upper_damage_bound: usize,
}

/// Wall time spent so far in the parts of the steps (for benchmarks; a few clock reads per step).
#[derive(Debug, Clone, Copy, Default)]
pub struct StepTimings {
    /// Load vectors of (5.1) and (5.2), the data fields' evaluation included.
    pub loads: std::time::Duration,
    /// The velocity step (5.1) (concurrent with the damage step when threads are free).
    pub velocity: std::time::Duration,
    /// The damage step (5.2).
    pub damage: std::time::Duration,
}

/// A running simulation of Problem P_V^hk.
pub struct Simulation<const D: usize> {
    problem: Problem<D>,
    space: Arc<LagrangeSpace<D>>,
    contact: Arc<ContactNodes<D>>,
    velocity: VelocityOperator<D>,
    /// None when the damage is frozen ([`DamageEvolution::Frozen`]).
    damage: Option<DamageOperator<D>>,
    loads: LoadQuadrature<D>,
    /// f0 and q at the cell quadrature points for the upcoming steps ([`BulkData`]; empty when
    /// the data ask for one time per evaluation).
    bulk: BulkData<D>,
    /// The facet quadrature points of each part of Γ1 (for its traction on free components).
    part_facets: Vec<FacetPoints<D>>,
    dirichlet: DirichletConstraints<D>,
    state: State,
    timings: StepTimings,
}

impl<const D: usize> Simulation<D> {
    /// Validates the problem, builds the spaces and operators (symbolic analyses), and sets the
    /// initial state u_0 = Π^h u0, β_0 = Π^h β0.
    pub fn new(problem: Problem<D>) -> Result<Self> {
        let model = &problem.model;
        model.viscosity.validate()?;
        model.elasticity.validate()?;
        if problem.settings.damage_evolution == DamageEvolution::Parabolic {
            model.damage_source.validate()?;
        }
        model.contact.validate()?;
        if !(problem.final_time.is_finite() && problem.final_time > 0.0) {
            return Err(Error::parameter(
                "final_time",
                problem.final_time,
                "T must be > 0",
            ));
        }
        if problem.steps == 0 {
            return Err(Error::parameter(
                "steps",
                0.0,
                "the number of time steps N must be ≥ 1",
            ));
        }
        let space = Arc::new(LagrangeSpace::new(problem.mesh.clone(), problem.degree)?);
        let dirichlet = DirichletConstraints::new(&space, &problem.data.dirichlet)?;
        check_rigid_motions(&space, &dirichlet)?;
        let contact = Arc::new(ContactNodes::with_constraints(
            &space,
            &dirichlet.constrained,
        )?);
        let mut velocity = VelocityOperator::with_constraints(
            space.clone(),
            model.viscosity.clone(),
            contact.clone(),
            dirichlet.constrained.clone(),
        )?;
        // the Newton tangents of the implicit normal compliance with a linear 𝒜 change the
        // contact block of the factor only: keep the body's factor for the whole run; without
        // friction the tangential contact unknowns are ordinary unknowns
        velocity.arrange_contact(
            !model.contact.is_frictionless(),
            problem.settings.contact == ContactTreatment::Implicit && model.viscosity.is_linear(),
        )?;
        let time_step = problem.final_time / problem.steps as f64;
        let damage = match problem.settings.damage_evolution {
            DamageEvolution::Parabolic => {
                let mut operator = DamageOperator::new(
                    space.clone(),
                    model.damage_diffusion,
                    time_step,
                    problem.settings.damage,
                )?;
                operator.set_bound_set_prediction(problem.settings.damage_bound_sets);
                Some(operator)
            }
            DamageEvolution::Frozen => None,
        };
        let loads = LoadQuadrature::with_jump_planes(&space, &problem.data.jump_planes)?;
        let part_rule = FacetRule::new(D, 2 * space.degree() + 2);
        let part_facets = (0..dirichlet.parts.len())
            .map(|p| FacetPoints::new(&space, &part_rule, |f| dirichlet.facet_owner[f] == Some(p)))
            .collect();
        gap_values(&space, &contact, &problem.data.gap, 0.0)?;
        let mut displacement = space.interpolate_vector(|x| (problem.data.initial_displacement)(x));
        let prescribed = dirichlet.values(&space, 0.0)?;
        for &(dof, owner) in &dirichlet.dofs {
            let (u, u_d) = (displacement[dof], prescribed[dof]);
            let matches = (u - u_d).abs() <= 1e-12 * (1.0 + u_d.abs());
            if !matches {
                let node = dof / D;
                return Err(Error::parameter(
                    format!(
                        "initial_displacement at node {node} {:?}, component {}, on Γ1 part `{}`",
                        space.node(node),
                        dof % D,
                        dirichlet.names[owner]
                    ),
                    u,
                    format!("u0 must equal the prescribed u_D(x, 0) = {u_d} on Γ1 (2.5)"),
                ));
            }
            displacement[dof] = u_d;
        }
        let damage_values = space.interpolate_scalar(|x| (problem.data.initial_damage)(x));
        if let Some(i) = damage_values.iter().position(|b| !(0.0..=1.0).contains(b)) {
            return Err(Error::parameter(
                format!("initial_damage at node {i} {:?}", space.node(i)),
                damage_values[i],
                "β0 must take values in [0, 1]",
            ));
        }
        if let Some(i) = displacement.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite(format!(
                "initial displacement at node {}",
                i / D
            )));
        }
        let state = State {
            step: 0,
            time: 0.0,
            velocity: vec![0.0; displacement.len()],
            displacement,
            damage: damage_values,
            previous_damage: Vec::new(),
        };
        Ok(Self {
            problem,
            space,
            contact,
            velocity,
            damage,
            loads,
            bulk: BulkData::default(),
            part_facets,
            dirichlet,
            state,
            timings: StepTimings::default(),
        })
    }

    /// Wall time spent so far in the loads and the two solves of the steps.
    pub fn timings(&self) -> &StepTimings {
        &self.timings
    }

    /// Names of the parts of Γ1, in the order of [`StepReport::reactions`]: the parts of
    /// [`Data::dirichlet`], then [`crate::model::dirichlet::CLAMPED_PART`] if some Γ1 facet belongs
    /// to no part.
    pub fn dirichlet_parts(&self) -> &[String] {
        &self.dirichlet.names
    }

    /// The resultant reaction of each part of Γ1 (order of [`Self::dirichlet_parts`]) from the
    /// nodal reactions of a velocity step ([`VelocitySolution::reaction`]).
    pub fn part_reactions(&self, reaction: &[f64]) -> Vec<[f64; D]> {
        self.dirichlet.resultants(reaction)
    }

    /// g(a, t) at the contact nodes; a non-finite value is an error naming the node.
    pub fn gap_at(&self, time: f64) -> Result<Vec<f64>> {
        gap_values(&self.space, &self.contact, &self.problem.data.gap, time)
    }

    /// The current state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Replaces the current state (restart from saved fields).
    pub fn set_state(&mut self, state: State) -> Result<()> {
        let n = self.space.num_nodes();
        if state.displacement.len() != n * D
            || state.velocity.len() != n * D
            || state.damage.len() != n
            || !(state.previous_damage.is_empty() || state.previous_damage.len() == n)
        {
            return Err(Error::InvalidInput(
                "state does not match the finite element space".into(),
            ));
        }
        self.state = state;
        Ok(())
    }

    /// The finite element space.
    pub fn space(&self) -> &Arc<LagrangeSpace<D>> {
        &self.space
    }

    /// The contact nodes.
    pub fn contact(&self) -> &Arc<ContactNodes<D>> {
        &self.contact
    }

    /// The velocity operator (sizes, for reporting).
    pub fn velocity_operator(&self) -> &VelocityOperator<D> {
        &self.velocity
    }

    /// Time step k = T/N.
    pub fn time_step(&self) -> f64 {
        self.problem.final_time / self.problem.steps as f64
    }

    /// Number of steps N.
    pub fn steps(&self) -> usize {
        self.problem.steps
    }

    /// Loads of step n at t_n from the state n−1: the velocity load (Cartesian, node-major) and
    /// the damage source ⟨φ(ε(u_{n−1}), β_{n−1}) + q(t_n), φ_a⟩ + ∫_Γ κ∂β/∂ν φ_a.
    pub fn step_loads(&self, time: f64) -> (Vec<f64>, Vec<f64>) {
        let (mut velocity_load, damage_source) = self.loads.assemble(
            &self.space,
            &self.problem.model,
            &self.problem.data,
            time,
            &self.state,
            Some(&self.bulk),
        );
        self.add_part_tractions(time, &mut velocity_load);
        (velocity_load, damage_source)
    }

    /// Makes [`Simulation::bulk`] hold f0 and q at t_n: if it does not, evaluates them at
    /// t_n, t_{n+1}, … (as many step times as [`LoadQuadrature::times_per_block`] allows, up
    /// to t_N). The times are those [`Simulation::step`] computes, bit for bit.
    fn prepare_bulk_data(&mut self, n: usize) {
        let k = self.time_step();
        let time = n as f64 * k;
        let per_block = self.loads.times_per_block(&self.problem.data);
        if per_block <= 1 || self.bulk.holds(time) {
            return;
        }
        let last = (n + per_block - 1).min(self.problem.steps).max(n);
        let times: Vec<f64> = (n..=last).map(|m| m as f64 * k).collect();
        // The new block is evaluated in the buffers of the old one.
        let spent = std::mem::take(&mut self.bulk);
        self.bulk = self.loads.bulk_data_into(&self.problem.data, &times, spent);
    }

    /// The step limit of the explicit terms of (5.1) at the current state ([`crate::scheme::stability`]):
    /// with the paper's explicit normal compliance the elastic and contact stiffness, with the
    /// implicit one the elastic stiffness only. A run with k above it is unstable.
    /// The factor of the viscous operator it solves with is the one the following linear steps
    /// use ([`VelocityOperator::factorize_viscous`]).
    pub fn step_limit(&mut self) -> Result<StepLimit> {
        let penetrations = self.penetrations(&self.gap_at(self.state.time)?);
        step_limit(
            &mut self.velocity,
            self.problem.model.elasticity.as_ref(),
            self.problem.model.contact.as_ref(),
            &penetrations,
            self.problem.settings.contact == ContactTreatment::Explicit,
        )
    }

    /// ∫ f·φ_a e_i over the facets of each part of Γ1 with a traction, on its free components i.
    fn add_part_tractions(&self, time: f64, velocity_load: &mut [f64]) {
        for (part, facets) in self.dirichlet.parts.iter().zip(&self.part_facets) {
            let Some(traction) = &part.traction else {
                continue;
            };
            let mut data = vec![0.0; facets.len() * D];
            for ((x, normal), out) in facets
                .points
                .iter()
                .zip(&facets.normals)
                .zip(data.chunks_mut(D))
            {
                let value = traction(x, time, normal);
                for i in (0..D).filter(|&i| part.components[i].is_none()) {
                    out[i] = value[i];
                }
            }
            facets.scatter(&self.space, D, &data, velocity_load);
        }
    }

    /// Penetrations u_ν(a) − g(a) of the current state at the contact nodes, for the gap
    /// values `gap` (of [`Self::gap_at`]).
    fn penetrations(&self, gap: &[f64]) -> Vec<f64> {
        (0..self.contact.len())
            .map(|k| {
                let node = self.contact.nodes[k];
                let u = SVector::<f64, D>::from_column_slice(
                    &self.state.displacement[node * D..node * D + D],
                );
                u.dot(&self.contact.normal(k)) - gap[k]
            })
            .collect()
    }

    /// One step of the scheme: (5.1) and (5.2) concurrently, then (5.4)–(5.5). On Γ1 the
    /// velocity step takes v_c = (u_D(t_n) − u_{n−1,c})/k and u_n = u_D(t_n) is set exactly;
    /// p_ν and p_τ take the gap at t_{n−1} (the implicit normal compliance at t_n). Returns the
    /// velocity and damage solutions, the normal pressure of the step and the friction bound.
    pub fn step(&mut self) -> Result<StepOutcome> {
        let n = self.state.step + 1;
        let time = n as f64 * self.time_step();
        let started = std::time::Instant::now();
        self.prepare_bulk_data(n);
        let (velocity_load, damage_source) = self.step_loads(time);
        self.check_damage_range((n - 1) as f64 * self.time_step())?;
        self.timings.loads += started.elapsed();
        let k = self.time_step();
        let previous_time = (n - 1) as f64 * k;
        // p_ν and p_τ of (5.1) at u_{n−1} − g(t_{n−1})
        let penetrations = self.penetrations(&self.gap_at(previous_time)?);
        // u_D(t_n) on Γ1: v_c = (u_D(t_n) − u_{n−1,c})/k
        let prescribed_displacement = self.dirichlet.values(&self.space, time)?;
        let mut prescribed = vec![0.0; prescribed_displacement.len()];
        for &(dof, _) in &self.dirichlet.dofs {
            prescribed[dof] = (prescribed_displacement[dof] - self.state.displacement[dof]) / k;
        }
        let law = &self.problem.model.contact;
        let normal_pressure: Vec<f64> = penetrations
            .iter()
            .map(|&r| law.normal_pressure(r))
            .collect();
        let friction_bound: Vec<f64> = penetrations
            .iter()
            .map(|&r| law.friction_bound(r))
            .collect();
        let implicit = self.problem.settings.contact == ContactTreatment::Implicit;
        let data = VelocityData {
            load: &velocity_load,
            normal_pressure: &normal_pressure,
            friction_bound: &friction_bound,
            implicit_contact: if implicit {
                Some(ImplicitNormalCompliance {
                    // u_{n−1,ν} − g(t_n): the end-of-step penetration is this plus k v_ν
                    previous_penetration: self.penetrations(&self.gap_at(time)?),
                    time_step: k,
                    law: law.clone(),
                })
            } else {
                None
            },
            prescribed: Some(&prescribed),
        };
        let settings = self.problem.settings.velocity;
        let previous_velocity = &self.state.velocity;
        let previous_damage = &self.state.damage;
        let before_previous_damage = &self.state.previous_damage;
        let velocity_op = &mut self.velocity;
        let damage_op = &mut self.damage;
        let ((velocity, velocity_time), (damage, damage_time)) = rayon::join(
            || {
                let started = std::time::Instant::now();
                let velocity = velocity_op.solve(&data, previous_velocity, &settings);
                (velocity, started.elapsed())
            },
            || {
                let started = std::time::Instant::now();
                let damage = match damage_op {
                    Some(operator) => {
                        operator.solve(&damage_source, previous_damage, before_previous_damage)
                    }
                    None => Ok(DamageSolution {
                        damage: previous_damage.clone(),
                        stats: BoxQpStats::default(),
                    }),
                };
                (damage, started.elapsed())
            },
        );
        self.timings.velocity += velocity_time;
        self.timings.damage += damage_time;
        let velocity = velocity?;
        let damage = damage?;
        for (u, v) in self.state.displacement.iter_mut().zip(&velocity.velocity) {
            *u += k * v;
        }
        // u_n = u_D(t_n) on Γ1 exactly (u_{n−1} + k v_n agrees up to rounding)
        for &(dof, _) in &self.dirichlet.dofs {
            self.state.displacement[dof] = prescribed_displacement[dof];
        }
        self.state.velocity.clone_from(&velocity.velocity);
        std::mem::swap(&mut self.state.previous_damage, &mut self.state.damage);
        self.state.damage.clone_from(&damage.damage);
        self.state.step = n;
        self.state.time = time;
        // the pressure the step used: p_ν at u_{n−1} (5.1), or at u_n = u_{n−1} + k v_n
        let normal_pressure = if implicit {
            let law = &self.problem.model.contact;
            self.penetrations(&self.gap_at(time)?)
                .iter()
                .map(|&r| law.normal_pressure(r))
                .collect()
        } else {
            normal_pressure
        };
        Ok(StepOutcome {
            velocity,
            damage,
            normal_pressure,
            friction_bound,
        })
    }

    /// The elasticity law inside its admissible range
    /// ([`crate::model::laws::Elasticity::damage_range_violation`]) at the damage β_{n−1} of
    /// every quadrature point where the loads of the step evaluated it: otherwise an error
    /// naming the law's key, the point and the time `time` = t_{n−1} of the damage. The points
    /// are searched only once the law has noted an evaluation outside its range
    /// ([`crate::model::laws::Elasticity::damage_range_suspect`]).
    fn check_damage_range(&self, time: f64) -> Result<()> {
        let law = self.problem.model.elasticity.as_ref();
        if !law.damage_range_suspect() {
            return Ok(());
        }
        let found = self
            .loads
            .first_damage_point(&self.space, &self.state.damage, |beta| {
                law.damage_range_violation(beta).is_some()
            });
        let Some((point, beta)) = found else {
            return Ok(());
        };
        match law.damage_range_violation(beta) {
            Some(Error::InvalidParameter {
                name,
                value,
                reason,
            }) => Err(Error::InvalidParameter {
                name,
                value,
                reason: format!(
                    "{reason}, reached by the damage β = {beta} of the run at the quadrature \
                     point {point:?} at t = {time}"
                ),
            }),
            Some(other) => Err(other),
            None => Ok(()),
        }
    }

    /// Runs the remaining steps up to N, calling `observer` after each.
    pub fn run(
        &mut self,
        mut observer: impl FnMut(&StepReport<'_, D>) -> Result<()>,
    ) -> Result<RunSummary> {
        let mut summary = RunSummary::default();
        while self.state.step < self.problem.steps {
            let StepOutcome {
                velocity,
                damage,
                normal_pressure,
                friction_bound,
            } = self.step()?;
            summary.steps += 1;
            summary.max_velocity_kkt = summary.max_velocity_kkt.max(velocity.stats.kkt_residual);
            summary.max_damage_kkt = summary.max_damage_kkt.max(damage.stats.kkt_residual);
            summary.velocity_newton_iterations += velocity.stats.newton_iterations;
            if velocity.stats.newton_iterations > summary.max_velocity_newton_iterations {
                summary.max_velocity_newton_iterations = velocity.stats.newton_iterations;
                summary
                    .slowest_velocity_history
                    .clone_from(&velocity.stats.residual_history);
            }
            summary.friction_iterations += velocity.stats.friction_iterations;
            summary.damage_iterations += damage.stats.iterations;
            summary.velocity_factorizations += velocity.stats.factorizations;
            summary.damage_factorizations += damage.stats.factorizations;
            let steps_with = &mut summary.steps_with_status;
            for (count, status) in [
                (&mut steps_with.separated, ContactStatus::Separated),
                (&mut steps_with.stick, ContactStatus::Stick),
                (&mut steps_with.slip, ContactStatus::Slip),
            ] {
                if velocity.status.contains(&status) {
                    *count += 1;
                }
            }
            if damage.stats.lower_active > 0 {
                summary.steps_with_lower_damage_bound += 1;
            }
            if damage.stats.upper_active > 0 {
                summary.steps_with_upper_damage_bound += 1;
            }
            let reactions = self.part_reactions(&velocity.reaction);
            observer(&StepReport {
                state: &self.state,
                space: &self.space,
                contact: &self.contact,
                contact_status: &velocity.status,
                normal_pressure: &normal_pressure,
                friction_bound: &friction_bound,
                multipliers: &velocity.multipliers,
                reactions: &reactions,
                velocity_stats: &velocity.stats,
                damage_stats: &damage.stats,
            })?;
        }
        Ok(summary)
    }
}

/// g(a, t) at the contact nodes a; a non-finite value is an [`Error::NonFinite`] naming the
/// node, its position and t.
fn gap_values<const D: usize>(
    space: &LagrangeSpace<D>,
    contact: &ContactNodes<D>,
    gap: &PointScalarField<D>,
    time: f64,
) -> Result<Vec<f64>> {
    contact
        .nodes
        .iter()
        .map(|&node| {
            let x = space.node(node);
            let value = gap(&x, time);
            if value.is_finite() {
                Ok(value)
            } else {
                Err(Error::NonFinite(format!(
                    "gap g = {value} at contact node {node} {x:?}, t = {time}"
                )))
            }
        })
        .collect()
}
