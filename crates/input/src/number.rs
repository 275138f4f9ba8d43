//! Numbers in messages.

/// A time or value printed short: the shortest round-trip decimal when it has at most 12
/// significant characters, scientific notation otherwise (never 300 digits for 1e300).
pub fn short(value: f64) -> String {
    let plain = format!("{value}");
    if plain.len() <= 12 {
        plain
    } else {
        format!("{value:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_never_prints_hundreds_of_digits() {
        assert_eq!(short(0.2), "0.2");
        assert_eq!(short(1e300), "1e300");
        assert_eq!(short(4.0), "4");
        assert!(short(1.0 / 3.0).len() <= 22);
    }
}
