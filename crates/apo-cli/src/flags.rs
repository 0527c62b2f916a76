//! Parsers of command-line values shared by the subcommands.

/// A parser of a count flag in `low..=high` (for clap's `value_parser`) whose every error says
/// the range: clap's own says "number too large to fit in target type" for
/// `99999999999999999999` and "invalid digit found in string" for `-1`.
pub fn count<T: TryFrom<u64>>(
    low: u64,
    high: u64,
) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static {
    move |text| {
        text.trim()
            .parse::<u64>()
            .ok()
            .filter(|v| (low..=high).contains(v))
            .and_then(|v| T::try_from(v).ok())
            .ok_or_else(|| format!("`{text}` is not in {low}..={high}"))
    }
}
