//! One velocity step (5.1): the data are checked, the prescribed velocities on Γ1 lifted, the
//! load F formed in the system frame, the step solved (linear or nonlinear 𝒜) and the contact
//! status and reactions of the solution computed.

use super::operator::VelocityOperator;
use super::types::{VelocityData, VelocitySettings, VelocitySolution};
use crate::algebra::linalg::{first_out_of_scale, max_abs, within_scale, MAGNITUDE_LIMIT};
use crate::error::{Error, Result, StepDatum};
use crate::model::contact::ContactStatus;

impl<const D: usize> VelocityOperator<D> {
    /// Solves the velocity step (5.1) for the given data; `start` (Cartesian) is the initial
    /// guess of the outer Newton iteration (ignored for a linear 𝒜).
    pub fn solve(
        &mut self,
        data: &VelocityData<'_>,
        start: &[f64],
        settings: &VelocitySettings,
    ) -> Result<VelocitySolution> {
        self.check_data(data)?;
        self.set_prescribed(data)?;
        // the force of the prescribed velocities on the free unknowns, K_fc p_c (linear 𝒜: its
        // lifting; nonlinear: its first-order part), in the system frame
        let lifting = if self.prescribed_cartesian.iter().any(|&p| p != 0.0) {
            Some(self.to_system(&self.constrained_cell_force(&self.prescribed_cartesian)))
        } else {
            None
        };
        self.lifting_scale = lifting.as_ref().map_or(0.0, |l| max_abs(l));
        // F in the system frame, with the explicit normal compliance load −ω_a p_ν on the
        // normal unknown (the implicit one is part of N(v) instead).
        let mut load = self.to_system(data.load);
        if data.implicit_contact.is_none() {
            for (k, &node) in self.contact.nodes.iter().enumerate() {
                load[node * D] -= self.contact.weights[k] * data.normal_pressure[k];
            }
        }
        let weights = self.friction_weights(data.friction_bound)?;
        if self.tangential.is_empty() && !self.contact.is_empty() {
            if let Some(k) = weights.iter().position(|&w| w > 0.0) {
                return Err(Error::InvalidInput(format!(
                    "velocity step: friction bound {} at contact node {} ({:?}), but the operator \
                     was built without friction (the contact law has μ = 0)",
                    data.friction_bound[k],
                    self.contact.nodes[k],
                    self.space.node(self.contact.nodes[k])
                )));
            }
        }
        self.implicit.clone_from(&data.implicit_contact);
        if self.implicit.is_some() {
            // the tangent depends on the step's penetrations, not only on v
            self.linearized_at = None;
        }
        let (velocity, multipliers, stats) = if self.law.is_linear() && self.implicit.is_none() {
            // eliminate the prescribed velocities: F_f − K_fc p_c on the free rows, p_c on the
            // constrained (identity) rows
            if let Some(lifting) = &lifting {
                for ((f, l), &c) in load.iter_mut().zip(lifting).zip(&self.constrained) {
                    if !c {
                        *f -= l;
                    }
                }
            }
            for (dof, _) in self.constrained.iter().enumerate().filter(|(_, &c)| c) {
                load[dof] = self.prescribed[dof];
            }
            self.solve_linear(&load, &weights, start, settings)?
        } else {
            self.solve_nonlinear(&load, &weights, start, settings)?
        };
        let status = self.contact_status(data, &weights, &velocity);
        let velocity = self.to_cartesian(&velocity);
        let reaction = self.reactions(data.load, &velocity);
        Ok(VelocitySolution {
            velocity,
            multipliers,
            status,
            reaction,
            stats,
        })
    }

    /// The sizes and values of the data of a step: finite loads, pressures and friction
    /// bounds ≥ 0, and the implicit normal compliance's penetrations and time step.
    fn check_data(&self, data: &VelocityData<'_>) -> Result<()> {
        let k_count = self.contact.len();
        let size = self.size();
        if data.load.len() != size
            || data.normal_pressure.len() != k_count
            || data.friction_bound.len() != k_count
        {
            return Err(Error::InvalidInput(format!(
                "velocity step data sizes: load {} (expected {size}), normal pressure {} and friction bound {} (expected {k_count})",
                data.load.len(),
                data.normal_pressure.len(),
                data.friction_bound.len()
            )));
        }
        // one pass per vector: the first value that is not finite (or negative), or beyond the
        // scale of double precision
        if let Some(i) = first_out_of_scale(data.load) {
            let (node, component) = (i / D, i % D);
            return Err(if data.load[i].is_finite() {
                out_of_scale(
                    StepDatum::Load,
                    format!("the load at node {node} (component {component})"),
                    data.load[i],
                )
            } else {
                non_finite(
                    StepDatum::Load,
                    format!(
                        "velocity step load vector at dof {i} (node {node}, component {component})"
                    ),
                )
            });
        }
        for (name, values) in [
            ("normal pressure", data.normal_pressure),
            ("friction bound", data.friction_bound),
        ] {
            if let Some(k) = values.iter().position(|&v| !within_scale(v) || v < 0.0) {
                let (node, value) = (self.contact.nodes[k], values[k]);
                let at = self.space.node(node);
                return Err(if value.is_finite() && value >= 0.0 {
                    out_of_scale(
                        StepDatum::Contact,
                        format!("the {name} at contact node {node} ({at:?})"),
                        value,
                    )
                } else {
                    non_finite(
                        StepDatum::Contact,
                        format!(
                            "{name} {value} at contact node {node} ({at:?}) must be finite and ≥ 0"
                        ),
                    )
                });
            }
        }
        if let Some(implicit) = &data.implicit_contact {
            if implicit.previous_penetration.len() != k_count {
                return Err(Error::InvalidInput(format!(
                    "implicit normal compliance: {} penetrations for {k_count} contact nodes",
                    implicit.previous_penetration.len()
                )));
            }
            if !(implicit.time_step.is_finite() && implicit.time_step > 0.0) {
                return Err(Error::parameter(
                    "time_step",
                    implicit.time_step,
                    "the implicit normal compliance needs a finite time step k > 0",
                ));
            }
            let penetration = &implicit.previous_penetration;
            if let Some(k) = first_out_of_scale(penetration) {
                let node = self.contact.nodes[k];
                let at = self.space.node(node);
                return Err(if penetration[k].is_finite() {
                    out_of_scale(
                        StepDatum::Contact,
                        format!("the penetration u_ν − g at contact node {node} ({at:?})"),
                        penetration[k],
                    )
                } else {
                    non_finite(
                        StepDatum::Contact,
                        format!(
                            "penetration u_ν − g = {} at contact node {node} ({at:?})",
                            penetration[k]
                        ),
                    )
                });
            }
        }
        Ok(())
    }

    /// Takes the prescribed velocities of the step on the constrained unknowns (zero when the
    /// data has none), checking their number and finiteness: Cartesian, and in the system frame
    /// (at a contact node, the fixed frame components ±e_i · v).
    fn set_prescribed(&mut self, data: &VelocityData<'_>) -> Result<()> {
        let size = self.size();
        self.prescribed.fill(0.0);
        self.prescribed_cartesian.fill(0.0);
        if let Some(prescribed) = data.prescribed {
            if prescribed.len() != size {
                return Err(Error::InvalidInput(format!(
                    "velocity step: {} prescribed velocities for {size} unknowns",
                    prescribed.len()
                )));
            }
            for (dof, _) in self
                .constrained_cartesian
                .iter()
                .enumerate()
                .filter(|(_, &c)| c)
            {
                if !prescribed[dof].is_finite() {
                    return Err(non_finite(
                        StepDatum::PrescribedVelocity,
                        format!(
                            "prescribed velocity {} at node {} ({:?}), component {}",
                            prescribed[dof],
                            dof / D,
                            self.space.node(dof / D),
                            dof % D
                        ),
                    ));
                }
                if !within_scale(prescribed[dof]) {
                    return Err(out_of_scale(
                        StepDatum::PrescribedVelocity,
                        format!(
                            "the prescribed velocity at node {} ({:?}), component {}",
                            dof / D,
                            self.space.node(dof / D),
                            dof % D
                        ),
                        prescribed[dof],
                    ));
                }
                self.prescribed_cartesian[dof] = prescribed[dof];
            }
            for (dof, _) in self.constrained.iter().enumerate().filter(|(_, &c)| c) {
                let (node, component) = (dof / D, dof % D);
                self.prescribed[dof] = match self.contact.index_of_node[node] {
                    None => self.prescribed_cartesian[dof],
                    // a fixed tangent of a contact frame: t · v
                    Some(k) => (0..D)
                        .map(|i| {
                            self.contact.frames[k][(i, component)]
                                * self.prescribed_cartesian[node * D + i]
                        })
                        .sum(),
                };
            }
        }
        Ok(())
    }

    /// The status of each contact node at the solution (system frame): separated where the
    /// normal pressure vanishes, stick where a node with friction does not slide, slip otherwise.
    fn contact_status(
        &self,
        data: &VelocityData<'_>,
        weights: &[f64],
        velocity: &[f64],
    ) -> Vec<ContactStatus> {
        self.contact
            .nodes
            .iter()
            .enumerate()
            .map(|(k, &node)| {
                let pressure = match &self.implicit {
                    Some(implicit) => implicit
                        .law
                        .normal_pressure(implicit.penetration(k, velocity[node * D])),
                    None => data.normal_pressure[k],
                };
                if pressure <= 0.0 {
                    ContactStatus::Separated
                } else if weights[k] > 0.0 && (1..D).all(|i| velocity[node * D + i] == 0.0) {
                    ContactStatus::Stick
                } else {
                    ContactStatus::Slip
                }
            })
            .collect()
    }
}

/// [`Error::StepData`] for a non-finite `quantity`, described by `what`.
fn non_finite(quantity: StepDatum, what: String) -> Error {
    Error::StepData {
        quantity,
        out_of_scale: false,
        message: format!("non-finite value: {what}"),
    }
}

/// [`Error::StepData`] for `what` = `value` beyond [`MAGNITUDE_LIMIT`].
fn out_of_scale(quantity: StepDatum, what: String, value: f64) -> Error {
    Error::StepData {
        quantity,
        out_of_scale: true,
        message: format!(
            "out of scale: {what} is {value:e}, beyond {MAGNITUDE_LIMIT:e} in magnitude, where the squared norms and energies of the velocity step overflow; the data are out of the scale of double precision (change the problem's units)"
        ),
    }
}
