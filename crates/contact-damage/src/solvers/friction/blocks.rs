//! Block operations on the groups x_a ∈ R^G of the friction problem of (5.1): the Euclidean
//! norm |x_a| and block soft-thresholding, the prox of a weighted norm.

/// The Euclidean norm |x_a| of a block (the absolute value when G = 1).
pub(super) fn block_norm(block: &[f64]) -> f64 {
    match block {
        [single] => single.abs(),
        [first, second] => first.hypot(*second),
        _ => block.iter().map(|v| v * v).sum::<f64>().sqrt(),
    }
}

/// Block soft-thresholding y ↦ max(0, 1 − threshold/|y|) y, in place.
pub(super) fn shrink(block: &mut [f64], threshold: f64) {
    let norm = block_norm(block);
    let factor = if norm > threshold {
        1.0 - threshold / norm
    } else {
        0.0
    };
    for value in block.iter_mut() {
        *value *= factor;
    }
}
