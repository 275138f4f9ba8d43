//! `[scheme]` of case and problem files: the variant of the scheme (5.1)–(5.5).

use contact_damage::scheme::ContactTreatment;
use serde::{Deserialize, Serialize};

/// `[scheme]` of case and problem files.
#[derive(Debug, Clone, Copy, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct SchemeFile {
    /// `contact = "explicit"` (default: p_ν at u_{n−1}, the paper's (5.1)) or `"implicit"`
    /// (p_ν at u_n = u_{n−1} + k v_n: stiff contact at any step; the friction bound stays at
    /// u_{n−1}).
    #[serde(default)]
    pub contact: ContactTreatmentFile,
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
}
