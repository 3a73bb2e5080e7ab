//! How messages print numbers.

/// A number as messages print it: plainly for ordinary magnitudes, in scientific notation
/// for very large or very small ones (4.9e-37, not 0.0000…49).
pub fn number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e7).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::number;

    #[test]
    fn tiny_and_huge_numbers_print_in_scientific_notation() {
        assert_eq!(number(-4.919614648739951e-37), "-4.919614648739951e-37");
        assert_eq!(number(2.5e9), "2.5e9");
        assert_eq!(number(0.01), "0.01");
        assert_eq!(number(0.0), "0");
        assert_eq!(number(f64::NAN), "NaN");
    }
}
