//! Range checks of settings, with errors that name the field.

use std::fmt;

/// An invalid hyperparameter: names the field, its value and the rule it breaks.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("invalid `{field}` = {value}: {rule}")]
pub struct ConfigError {
    /// The field's path, e.g. `trust_region.max_kl`.
    pub field: String,
    /// The offending value, as written.
    pub value: String,
    /// What the value must satisfy.
    pub rule: String,
}

/// `Ok` when `ok`, else the [`ConfigError`] of `field` = `value` breaking `rule`.
pub(crate) fn check(
    ok: bool,
    field: &str,
    value: impl fmt::Display,
    rule: &str,
) -> Result<(), ConfigError> {
    if ok {
        Ok(())
    } else {
        Err(ConfigError::new(field, value, rule))
    }
}

impl ConfigError {
    /// The error of `field` = `value` breaking `rule` (`"must be ≥ 0"`); a non-finite value
    /// breaks every range, and the rule then says so first (`"must be finite and ≥ 0"`).
    pub fn new(field: &str, value: impl fmt::Display, rule: &str) -> Self {
        let mut value = value.to_string();
        // a number of 300 digits (1e308 as f64 prints it) is written as a user reads it
        if value.len() > 24 {
            if let Ok(x) = value.parse::<f64>() {
                value = shown(x);
            }
        }
        let rule = match (value.as_str(), rule.strip_prefix("must be ")) {
            ("inf" | "-inf" | "NaN", Some(rest)) => format!("must be finite and {rest}"),
            ("inf" | "-inf" | "NaN", None) => format!("must be finite; {rule}"),
            _ => rule.to_string(),
        };
        Self {
            field: field.into(),
            value,
            rule,
        }
    }
}

/// `x` as a user reads it: scientific notation when it is very large or very small.
pub fn shown(x: f64) -> String {
    if x != 0.0 && x.is_finite() && !(1e-4..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        x.to_string()
    }
}

/// Whether `x` is finite and ≥ 0.
pub(crate) fn finite_nonneg(x: f64) -> bool {
    x.is_finite() && x >= 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_non_finite_value_is_called_so() {
        let e = check(false, "k", f64::INFINITY, "must be ≥ 0").unwrap_err();
        assert_eq!(e.rule, "must be finite and ≥ 0");
        let e = check(false, "lr", f64::NAN, "in (0, 1]").unwrap_err();
        assert_eq!(e.rule, "must be finite; in (0, 1]");
        let e = check(false, "k", -1.0, "must be ≥ 0").unwrap_err();
        assert_eq!(e.rule, "must be ≥ 0");
    }
}
