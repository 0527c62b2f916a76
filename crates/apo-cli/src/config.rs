//! Run configuration: TOML files, `--set key=value` overrides, validation.
//!
//! A run's configuration is built in layers: the paper's defaults for the algorithm, then
//! the `--config` file, then `--set` overrides and the dedicated flags (`--env`, `--seed`,
//! `--epochs`, …). Every key is checked: an unknown key is rejected with its dotted path
//! and the closest known key, a value of the wrong type names the key and the expected
//! type, and out-of-range values name the field and the rule.

use std::fmt;
use std::path::Path;

use apo_core::{AlgoConfig, Algorithm};
use serde::{Deserialize, Serialize};

/// The compute backend of the updates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum BackendKind {
    /// Burn's NdArray backend on the CPU.
    Cpu,
    /// Burn's wgpu backend (Vulkan; a GPU, or Mesa's software rasterizer).
    Wgpu,
}

impl fmt::Display for BackendKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            BackendKind::Cpu => "cpu",
            BackendKind::Wgpu => "wgpu",
        })
    }
}

/// Everything a training run needs; written to `config.toml` in the run directory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunConfig {
    /// Environment name (see `apo list`).
    pub env: String,
    /// Seed of everything random in the run.
    pub seed: u64,
    /// Number of epochs (paper: 200 continuous, 500 Atari).
    pub epochs: usize,
    /// Environment steps collected per epoch (paper: 30 000).
    pub steps_per_epoch: usize,
    /// Environments stepped together (the epoch's steps are split between them).
    pub num_envs: usize,
    /// Normalize observations with running statistics (saved in checkpoints).
    pub normalize_obs: bool,
    /// Backend of the updates.
    pub backend: BackendKind,
    /// Write a checkpoint every this many epochs (and always at the end).
    pub checkpoint_every: usize,
    /// Hidden layer sizes of the policy and value networks (paper: [64, 64]).
    pub hidden: Vec<usize>,
    /// Initial log standard deviation of Gaussian policies.
    pub init_log_std: f64,
    /// The algorithm's hyperparameters.
    pub algo: AlgoConfig,
}

/// A configuration error; the message names the key.
#[derive(Debug, thiserror::Error)]
pub enum ConfigFileError {
    /// The file could not be read.
    #[error("cannot read config file {path}: {source}")]
    Read {
        /// The path.
        path: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The TOML does not parse.
    #[error("config {origin} is not valid TOML: {message}")]
    Parse {
        /// Where the TOML came from.
        origin: String,
        /// The parser's message.
        message: String,
    },
    /// A key that no setting has.
    #[error("unknown config key `{key}`{}", suggestion.as_ref().map(|s| format!("; did you mean `{s}`?")).unwrap_or_default())]
    UnknownKey {
        /// Dotted path of the key.
        key: String,
        /// The closest known key.
        suggestion: Option<String>,
    },
    /// A value of the wrong type.
    #[error("config key `{key}`: {message}")]
    Type {
        /// Dotted path of the key.
        key: String,
        /// What was expected.
        message: String,
    },
    /// A malformed `--set` argument.
    #[error("--set expects key=value, got `{0}`")]
    BadSet(String),
    /// A value out of range.
    #[error(transparent)]
    Range(#[from] apo_core::ConfigError),
}

impl RunConfig {
    /// The paper's defaults for `algo` on `env`.
    pub fn defaults(algo: Algorithm, env: &str) -> Self {
        Self {
            env: env.to_string(),
            seed: 0,
            epochs: 200,
            steps_per_epoch: 30_000,
            num_envs: 1,
            normalize_obs: false,
            backend: BackendKind::Cpu,
            checkpoint_every: 1,
            hidden: vec![64, 64],
            init_log_std: -0.5,
            algo: AlgoConfig::paper_defaults(algo),
        }
    }

    /// Builds a configuration: defaults for `algo`, then the TOML `file` if any, then
    /// each `key=value` of `sets` (values in TOML syntax; a bare word is taken as a string).
    pub fn build(algo: Algorithm, env: &str, file: Option<&Path>, sets: &[String]) -> Result<Self, ConfigFileError> {
        let mut doc = to_table(&Self::defaults(algo, env));
        let chosen = toml::Value::String(algo.name().to_string());
        if let Some(path) = file {
            let text = std::fs::read_to_string(path)
                .map_err(|source| ConfigFileError::Read { path: path.display().to_string(), source })?;
            let layer: toml::Table = text
                .parse()
                .map_err(|e: toml::de::Error| ConfigFileError::Parse { origin: path.display().to_string(), message: e.to_string() })?;
            merge(&mut doc, layer, "")?;
        }
        for set in sets {
            let (key, value) = set.split_once('=').ok_or_else(|| ConfigFileError::BadSet(set.clone()))?;
            set_path(&mut doc, key.trim(), parse_value(value.trim()))?;
        }
        // the algorithm chosen on the command line wins over a file's
        set_path(&mut doc, "algo.algo", chosen)?;
        let config = Self::from_table(doc)?;
        config.validate()?;
        Ok(config)
    }

    /// Reads a configuration written by a run (`config.toml`), checking every key.
    pub fn load(path: &Path) -> Result<Self, ConfigFileError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| ConfigFileError::Read { path: path.display().to_string(), source })?;
        let table: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| ConfigFileError::Parse { origin: path.display().to_string(), message: e.to_string() })?;
        let mut doc = to_table(&Self::defaults(Algorithm::Apo, ""));
        merge(&mut doc, table, "")?;
        let config = Self::from_table(doc)?;
        config.validate()?;
        Ok(config)
    }

    fn from_table(doc: toml::Table) -> Result<Self, ConfigFileError> {
        serde_path_to_error::deserialize(toml::Value::Table(doc)).map_err(|e| ConfigFileError::Type {
            key: e.path().to_string(),
            message: e.into_inner().to_string(),
        })
    }

    /// Checks the ranges of every field.
    pub fn validate(&self) -> Result<(), apo_core::ConfigError> {
        let fail = |field: &str, value: String, rule: &str| {
            Err(apo_core::ConfigError { field: field.into(), value, rule: rule.into() })
        };
        if self.epochs == 0 {
            return fail("epochs", self.epochs.to_string(), "must be ≥ 1");
        }
        if self.num_envs == 0 {
            return fail("num_envs", self.num_envs.to_string(), "must be ≥ 1");
        }
        if self.steps_per_epoch < self.num_envs {
            return fail("steps_per_epoch", self.steps_per_epoch.to_string(), "must be ≥ num_envs");
        }
        if self.checkpoint_every == 0 {
            return fail("checkpoint_every", self.checkpoint_every.to_string(), "must be ≥ 1");
        }
        if self.hidden.is_empty() || self.hidden.contains(&0) {
            return fail("hidden", format!("{:?}", self.hidden), "must be a non-empty list of positive sizes");
        }
        if !self.init_log_std.is_finite() {
            return fail("init_log_std", self.init_log_std.to_string(), "must be finite");
        }
        self.algo.validate().map_err(|e| apo_core::ConfigError { field: format!("algo.{}", e.field), ..e })
    }

    /// The configuration as TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_else(|e| format!("# could not serialize the config: {e}\n"))
    }
}

fn to_table<T: Serialize>(value: &T) -> toml::Table {
    match toml::Value::try_from(value) {
        Ok(toml::Value::Table(t)) => t,
        _ => toml::Table::new(),
    }
}

/// Keys that are optional (absent means `None`) and so missing from the defaults' table.
const OPTIONAL_KEYS: &[&str] = &[
    "algo.policy_update.target_kl",
    "algo.policy_update.minibatch_size",
    "algo.value_update.target_kl",
    "algo.value_update.minibatch_size",
];

/// All dotted keys of `table`, for suggestions.
fn all_keys(table: &toml::Table, prefix: &str, out: &mut Vec<String>) {
    for (k, v) in table {
        let key = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
        if let toml::Value::Table(t) = v {
            all_keys(t, &key, out);
        }
        out.push(key);
    }
}

fn unknown(key: &str, doc_keys: &[String]) -> ConfigFileError {
    let suggestion = doc_keys
        .iter()
        .map(String::as_str)
        .chain(OPTIONAL_KEYS.iter().copied())
        .map(|k| (strsim::jaro_winkler(k, key), k))
        .filter(|(score, _)| *score > 0.8)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, k)| k.to_string());
    ConfigFileError::UnknownKey { key: key.to_string(), suggestion }
}

/// Merges `layer` into `base`, rejecting keys `base` does not have.
fn merge(base: &mut toml::Table, layer: toml::Table, prefix: &str) -> Result<(), ConfigFileError> {
    let mut keys = Vec::new();
    all_keys(base, prefix, &mut keys);
    for (k, v) in layer {
        let key = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(t)) => merge(b, t, &key)?,
            (Some(slot), v) => *slot = v,
            (None, v) if OPTIONAL_KEYS.contains(&key.as_str()) => {
                base.insert(k, v);
            }
            (None, _) => return Err(unknown(&key, &keys)),
        }
    }
    Ok(())
}

/// Sets the dotted `key` of `doc` to `value`.
fn set_path(doc: &mut toml::Table, key: &str, value: toml::Value) -> Result<(), ConfigFileError> {
    let mut layer = toml::Table::new();
    let parts: Vec<&str> = key.split('.').collect();
    let (last, parents) = parts.split_last().ok_or_else(|| ConfigFileError::BadSet(key.to_string()))?;
    let mut cursor = &mut layer;
    for p in parents {
        cursor = match cursor.entry(p.to_string()).or_insert_with(|| toml::Value::Table(toml::Table::new())) {
            toml::Value::Table(t) => t,
            _ => return Err(ConfigFileError::BadSet(key.to_string())),
        };
    }
    cursor.insert(last.to_string(), value);
    merge(doc, layer, "")
}

/// A `--set` value: TOML syntax (`0.99`, `true`, `[64, 64]`, `"x"`), or a bare string.
fn parse_value(text: &str) -> toml::Value {
    format!("v = {text}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(text.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_override_defaults_and_unknown_keys_are_named() {
        let sets = vec!["algo.gamma=0.95".to_string(), "hidden=[32, 16]".to_string(), "env=CartPole-v1".into()];
        let c = RunConfig::build(Algorithm::Ppo, "Pendulum-v1", None, &sets).expect("valid");
        assert_eq!(c.algo.gamma, 0.95);
        assert_eq!(c.hidden, vec![32, 16]);
        assert_eq!(c.env, "CartPole-v1");

        let err = RunConfig::build(Algorithm::Apo, "x", None, &["algo.gama=0.9".into()]).unwrap_err();
        assert_eq!(err.to_string(), "unknown config key `algo.gama`; did you mean `algo.gamma`?");

        let err = RunConfig::build(Algorithm::Apo, "x", None, &["algo.k=\"seven\"".into()]).unwrap_err();
        assert!(err.to_string().starts_with("config key `algo.k`: invalid type"), "{err}");

        let err = RunConfig::build(Algorithm::Apo, "x", None, &["algo.gamma=1.0".into()]).unwrap_err();
        assert_eq!(err.to_string(), "invalid `algo.gamma` = 1: must be in [0, 1)");

        let c = RunConfig::build(Algorithm::Ppo, "x", None, &["algo.policy_update.minibatch_size=64".into()])
            .expect("optional key");
        assert_eq!(c.algo.policy_update.minibatch_size, Some(64));
    }

    #[test]
    fn shipped_configs_are_the_paper_defaults() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs");
        for algo in Algorithm::ALL {
            let file = dir.join(format!("{algo}.toml"));
            let c = RunConfig::build(algo, "x", Some(&file), &[]).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
            assert_eq!(c, RunConfig::defaults(algo, "x"), "{}", file.display());
        }
    }

    #[test]
    fn written_config_round_trips() {
        let c = RunConfig::defaults(Algorithm::Papo, "Hopper");
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("config.toml");
        std::fs::write(&path, c.to_toml()).expect("write");
        assert_eq!(RunConfig::load(&path).expect("load"), c);
    }
}
