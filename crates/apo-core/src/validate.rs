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
        Err(ConfigError {
            field: field.into(),
            value: value.to_string(),
            rule: rule.into(),
        })
    }
}

/// Whether `x` is finite and ≥ 0.
pub(crate) fn finite_nonneg(x: f64) -> bool {
    x.is_finite() && x >= 0.0
}
