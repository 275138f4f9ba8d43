//! `[scheme]` of case and problem files: the variant of the scheme (5.1)–(5.5).

use contact_damage::scheme::{ContactTreatment, DamageEvolution};
use serde::{Deserialize, Serialize};

/// `[scheme]` of case and problem files.
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct SchemeFile {
    /// `contact = "explicit"` (default: p_ν at u_{n−1}, the paper's (5.1)) or `"implicit"`
    /// (p_ν at u_n = u_{n−1} + k v_n: stiff contact at any step; the friction bound stays at
    /// u_{n−1}).
    #[serde(default)]
    pub contact: ContactTreatmentFile,
    /// `damage = true` (default: β evolves by the damage step (5.2)) or `false` (a pure
    /// contact problem: no damage step, β stays β0 (1 unless `initial_damage` is given), and
    /// `laws.damage_source` and `laws.damage_diffusion` may be left out).
    #[serde(default = "evolving", skip_serializing_if = "is_evolving")]
    pub damage: bool,
}

fn evolving() -> bool {
    true
}

/// Not serialized when true, so that the fingerprint of a scheme written by an earlier version
/// (without the key) is unchanged.
fn is_evolving(damage: &bool) -> bool {
    *damage
}

impl Default for SchemeFile {
    fn default() -> Self {
        Self {
            contact: ContactTreatmentFile::default(),
            damage: true,
        }
    }
}

/// The values of `scheme.contact`.
#[derive(Debug, Clone, Copy, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ContactTreatmentFile {
    /// p_ν at u_{n−1} (5.1).
    #[default]
    Explicit,
    /// p_ν at u_{n−1} + k v_n.
    Implicit,
}

impl SchemeFile {
    /// The solver's setting.
    pub fn contact_treatment(&self) -> ContactTreatment {
        match self.contact {
            ContactTreatmentFile::Explicit => ContactTreatment::Explicit,
            ContactTreatmentFile::Implicit => ContactTreatment::Implicit,
        }
    }

    /// The solver's setting of the damage step.
    pub fn damage_evolution(&self) -> DamageEvolution {
        if self.damage {
            DamageEvolution::Parabolic
        } else {
            DamageEvolution::Frozen
        }
    }
}
