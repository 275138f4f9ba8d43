//! The damage source φ(ε, β) of (2.2) (paper §2–3, assumption (3.6)): the trait, the truncated
//! Frémond–Nedjar source and a user closure.

use super::tensor::{check_finite, Tensor};
use crate::error::{Error, Result};

/// Damage source φ(ε, β) of (2.2). Assumption (3.6): Lipschitz in (ε, β).
pub trait DamageSource<const D: usize>: Send + Sync {
    /// φ(ε, β).
    fn source(&self, strain: &Tensor<D>, damage: f64) -> f64;
    /// φ at a batch of points: `out[p] = φ(strains[p], damages[p])` (all slices of one
    /// length). The load assembly calls this once per chunk of cells; the default calls
    /// [`DamageSource::source`] point by point, a law given by an interpreted expression
    /// evaluates it over the whole batch.
    fn source_batch(&self, strains: &[Tensor<D>], damages: &[f64], out: &mut [f64]) {
        for ((strain, &damage), value) in strains.iter().zip(damages).zip(out) {
            *value = self.source(strain, damage);
        }
    }
    /// φ at the points of cells on each of which the strain is constant (P1 on affine
    /// simplices, where the load assembly (5.2) has one ε(u_{n−1}) per cell): with `m` =
    /// `damages.len() / cell_strains.len()` points per cell, in cell order,
    /// `out[p] = φ(cell_strains[p / m], damages[p])`. `damages` and `out` have one length, a
    /// multiple of the number of cells. The default repeats each strain for the points of its
    /// cell and calls [`DamageSource::source_batch`]; a law that reduces ε to invariants
    /// overrides it to compute them once per cell, with bitwise the same values.
    fn source_cells(&self, cell_strains: &[Tensor<D>], damages: &[f64], out: &mut [f64]) {
        let per_cell = points_per_cell(cell_strains.len(), damages.len());
        let strains: Vec<Tensor<D>> = cell_strains
            .iter()
            .flat_map(|strain| std::iter::repeat_n(*strain, per_cell))
            .collect();
        self.source_batch(&strains, damages, out);
    }
    /// Checks the parameters against (3.6).
    fn validate(&self) -> Result<()>;
}

/// The number of points per cell of [`DamageSource::source_cells`]: `points / cells`, which
/// must divide exactly (0 without cells).
pub fn points_per_cell(cells: usize, points: usize) -> usize {
    let per_cell = points.checked_div(cells).unwrap_or(0);
    debug_assert_eq!(
        per_cell * cells,
        points,
        "points not a multiple of the cells"
    );
    per_cell
}

/// Truncated Frémond–Nedjar source (paper §2 and the remark after (3.7)):
///
/// φ(ε, β) = λ_D (1 − β̂)/β̂ − ½ min(ε·ε, E_max) + λ_w,  β̂ = min(max(β, β_*), 1).
///
/// The physical source φ_Fr = λ_D (1 − β)/β − ½ ε·ε + λ_w is not Lipschitz (it blows up as β → 0
/// and grows quadratically in ε). The truncation replaces β by β̂ ≥ β_* > 0 (Lipschitz constant
/// λ_D/β_*² in β) and caps the strain energy density ε·ε at E_max (Lipschitz constant √E_max in ε),
/// so (3.6) holds; it coincides with φ_Fr wherever β ≥ β_* and ε·ε ≤ E_max.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruncatedFremond {
    /// λ_D ≥ 0.
    pub lambda_d: f64,
    /// λ_w (the energy threshold term; any sign).
    pub lambda_w: f64,
    /// β_* ∈ (0, 1].
    pub damage_floor: f64,
    /// E_max > 0: cap of ε·ε.
    pub strain_energy_cap: f64,
}

impl<const D: usize> DamageSource<D> for TruncatedFremond {
    fn source(&self, strain: &Tensor<D>, damage: f64) -> f64 {
        let beta_hat = damage.clamp(self.damage_floor, 1.0);
        self.lambda_d * (1.0 - beta_hat) / beta_hat
            - 0.5 * strain.norm_squared().min(self.strain_energy_cap)
            + self.lambda_w
    }
    /// The strain energy term once per cell.
    fn source_cells(&self, cell_strains: &[Tensor<D>], damages: &[f64], out: &mut [f64]) {
        let per_cell = points_per_cell(cell_strains.len(), damages.len());
        if per_cell == 0 {
            return;
        }
        for (strain, (damages, out)) in cell_strains
            .iter()
            .zip(damages.chunks(per_cell).zip(out.chunks_mut(per_cell)))
        {
            let energy = 0.5 * strain.norm_squared().min(self.strain_energy_cap);
            for (value, &damage) in out.iter_mut().zip(damages) {
                let beta_hat = damage.clamp(self.damage_floor, 1.0);
                *value = self.lambda_d * (1.0 - beta_hat) / beta_hat - energy + self.lambda_w;
            }
        }
    }
    fn validate(&self) -> Result<()> {
        check_finite("damage_source.lambda_d", self.lambda_d)?;
        check_finite("damage_source.lambda_w", self.lambda_w)?;
        check_finite("damage_source.damage_floor", self.damage_floor)?;
        check_finite("damage_source.strain_energy_cap", self.strain_energy_cap)?;
        if self.lambda_d < 0.0 {
            return Err(Error::parameter(
                "damage_source.lambda_d",
                self.lambda_d,
                "λ_D must be ≥ 0",
            ));
        }
        if !(self.damage_floor > 0.0 && self.damage_floor <= 1.0) {
            return Err(Error::parameter(
                "damage_source.damage_floor",
                self.damage_floor,
                "β_* must lie in (0, 1] for φ to be Lipschitz (3.6)",
            ));
        }
        if self.strain_energy_cap <= 0.0 {
            return Err(Error::parameter(
                "damage_source.strain_energy_cap",
                self.strain_energy_cap,
                "E_max must be > 0",
            ));
        }
        Ok(())
    }
}

/// A user damage source given by a closure `(strain, damage) -> φ`. The user is responsible for
/// (3.6); `validate` only checks that φ is finite at ε = 0 for β ∈ {0, ½, 1}.
pub struct DamageSourceFn<F>(pub F);

impl<const D: usize, F> DamageSource<D> for DamageSourceFn<F>
where
    F: Fn(&Tensor<D>, f64) -> f64 + Send + Sync,
{
    fn source(&self, strain: &Tensor<D>, damage: f64) -> f64 {
        (self.0)(strain, damage)
    }
    fn validate(&self) -> Result<()> {
        for beta in [0.0, 0.5, 1.0] {
            let value = (self.0)(&Tensor::<D>::zeros(), beta);
            if !value.is_finite() {
                return Err(Error::parameter(
                    "damage_source(0, β)",
                    beta,
                    "user damage source is not finite",
                ));
            }
        }
        Ok(())
    }
}
