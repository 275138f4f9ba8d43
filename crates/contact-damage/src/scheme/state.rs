//! The discrete state of the scheme after step n: t_n, u_n, v_n, β_n (5.3)–(5.5).

/// The discrete state after step n.
#[derive(Debug, Clone)]
pub struct State {
    /// Step index n.
    pub step: usize,
    /// t_n = n k.
    pub time: f64,
    /// u_n, Cartesian node-major.
    pub displacement: Vec<f64>,
    /// v_n (zero for n = 0).
    pub velocity: Vec<f64>,
    /// β_n, nodal.
    pub damage: Vec<f64>,
    /// β_{n−1}, nodal, or empty (n = 0, or a state that is not continued): the start of the
    /// next damage step is extrapolated from β_n and β_{n−1} ([`DamageOperator::solve`](crate::scheme::damage::DamageOperator::solve)), so a
    /// restart that is to continue bit for bit needs it.
    pub previous_damage: Vec<f64>,
}
