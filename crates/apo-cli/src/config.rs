//! Run configuration: TOML files, `--set key=value` overrides, validation.
//!
//! A run's configuration is built in layers: the paper's defaults for the algorithm, then
//! the `--config` file, then `--set` overrides and the dedicated flags (`--env`, `--seed`,
//! `--epochs`, …). Every key is checked: an unknown key is rejected with its dotted path
//! and the closest known key, a value of the wrong type names the key and the expected
//! type, and out-of-range values name the field and the rule.

use std::fmt;
use std::path::Path;

use apo_core::{ActionKind, AlgoConfig, Algorithm};
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

/// Where the Fisher-vector products and the value fit run (`kernels`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum KernelsKind {
    /// The host kernels with the cpu backend, Burn's graph with wgpu.
    #[default]
    Auto,
    /// apo-core's f32 host kernels (`apo_core::Kernels::Host`).
    Host,
    /// Burn's graph on the run's backend (`apo_core::Kernels::Backend`).
    Backend,
}

impl KernelsKind {
    /// The choice for a run on `backend`.
    pub fn resolve(self, backend: BackendKind) -> apo_core::Kernels {
        match (self, backend) {
            (KernelsKind::Host, _) | (KernelsKind::Auto, BackendKind::Cpu) => {
                apo_core::Kernels::Host
            }
            (KernelsKind::Backend, _) | (KernelsKind::Auto, BackendKind::Wgpu) => {
                apo_core::Kernels::Backend
            }
        }
    }
}

impl fmt::Display for KernelsKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            KernelsKind::Auto => "auto",
            KernelsKind::Host => "host",
            KernelsKind::Backend => "backend",
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
    /// Where the Fisher-vector products and the value fit run.
    #[serde(default)]
    pub kernels: KernelsKind,
    /// Write a checkpoint every this many epochs (and always at the end and on interrupt).
    pub checkpoint_every: usize,
    /// Also keep the checkpoint of every this many epochs as `checkpoints/epoch-<N>`
    /// (0: keep only the latest).
    #[serde(default)]
    pub keep_checkpoint_every: usize,
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
            kernels: KernelsKind::Auto,
            checkpoint_every: 1,
            keep_checkpoint_every: 0,
            hidden: vec![64, 64],
            init_log_std: -0.5,
            algo: AlgoConfig::paper_defaults(algo),
        }
    }

    /// Builds a configuration: defaults for `algo`, then the TOML `file` if any, then
    /// each `key=value` of `sets` (values in TOML syntax; a bare word is taken as a string).
    pub fn build(
        algo: Algorithm,
        env: &str,
        file: Option<&Path>,
        sets: &[String],
    ) -> Result<Self, ConfigFileError> {
        let mut doc = to_table(&Self::defaults(algo, env));
        let chosen = toml::Value::String(algo.name().to_string());
        if let Some(path) = file {
            let text = std::fs::read_to_string(path).map_err(|source| ConfigFileError::Read {
                path: path.display().to_string(),
                source,
            })?;
            let layer: toml::Table =
                text.parse()
                    .map_err(|e: toml::de::Error| ConfigFileError::Parse {
                        origin: path.display().to_string(),
                        message: e.to_string(),
                    })?;
            merge(&mut doc, layer, "")?;
        }
        for set in sets {
            let (key, value) = set
                .split_once('=')
                .ok_or_else(|| ConfigFileError::BadSet(set.clone()))?;
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
        let text = std::fs::read_to_string(path).map_err(|source| ConfigFileError::Read {
            path: path.display().to_string(),
            source,
        })?;
        let table: toml::Table =
            text.parse()
                .map_err(|e: toml::de::Error| ConfigFileError::Parse {
                    origin: path.display().to_string(),
                    message: e.to_string(),
                })?;
        let mut doc = to_table(&Self::defaults(Algorithm::Apo, ""));
        merge(&mut doc, table, "")?;
        let config = Self::from_table(doc)?;
        config.validate()?;
        Ok(config)
    }

    fn from_table(doc: toml::Table) -> Result<Self, ConfigFileError> {
        serde_path_to_error::deserialize(toml::Value::Table(doc)).map_err(|e| {
            ConfigFileError::Type {
                key: e.path().to_string(),
                message: e.into_inner().to_string(),
            }
        })
    }

    /// Checks the ranges of every field.
    pub fn validate(&self) -> Result<(), apo_core::ConfigError> {
        let fail = |field: &str, value: String, rule: &str| {
            Err(apo_core::ConfigError {
                field: field.into(),
                value,
                rule: rule.into(),
            })
        };
        if self.epochs == 0 {
            return fail("epochs", self.epochs.to_string(), "must be ≥ 1");
        }
        if self.num_envs == 0 {
            return fail("num_envs", self.num_envs.to_string(), "must be ≥ 1");
        }
        if self.num_envs > MAX_NUM_ENVS {
            return fail(
                "num_envs",
                self.num_envs.to_string(),
                &format!("must be ≤ {MAX_NUM_ENVS}"),
            );
        }
        if self.steps_per_epoch < self.num_envs {
            return fail(
                "steps_per_epoch",
                self.steps_per_epoch.to_string(),
                "must be ≥ num_envs",
            );
        }
        if self.checkpoint_every == 0 {
            return fail(
                "checkpoint_every",
                self.checkpoint_every.to_string(),
                "must be ≥ 1",
            );
        }
        if self.hidden.is_empty() || self.hidden.contains(&0) {
            return fail(
                "hidden",
                format!("{:?}", self.hidden),
                "must be a non-empty list of positive sizes",
            );
        }
        if !(-20.0..=2.0).contains(&self.init_log_std) {
            return fail(
                "init_log_std",
                self.init_log_std.to_string(),
                "must be in [-20, 2]",
            );
        }
        if self.steps_per_epoch > MAX_STEPS_PER_EPOCH {
            return fail(
                "steps_per_epoch",
                self.steps_per_epoch.to_string(),
                &format!("must be ≤ {MAX_STEPS_PER_EPOCH}"),
            );
        }
        if self.hidden.len() > MAX_LAYERS || self.hidden.iter().any(|&h| h > MAX_WIDTH) {
            return fail(
                "hidden",
                format!("{:?}", self.hidden),
                &format!("must have at most {MAX_LAYERS} layers of at most {MAX_WIDTH} units"),
            );
        }
        if self.seed > i64::MAX as u64 {
            return fail(
                "seed",
                self.seed.to_string(),
                &format!(
                    "must be in 0..={} (TOML integers are signed 64-bit)",
                    i64::MAX
                ),
            );
        }
        self.algo.validate().map_err(|e| apo_core::ConfigError {
            field: format!("algo.{}", e.field),
            ..e
        })
    }

    /// Checks that a run of this configuration on an environment with `observation_dim`
    /// observations and `action` fits in this machine's memory ([`memory_estimate`]), before
    /// anything is allocated or created; the error names the keys that size it.
    pub fn check_memory(
        &self,
        observation_dim: usize,
        action: ActionKind,
    ) -> Result<(), apo_core::ConfigError> {
        let need = memory_estimate(self, observation_dim, action);
        let have = physical_memory().unwrap_or(MEMORY_WITHOUT_PROC);
        if need > have as f64 {
            return Err(apo_core::ConfigError {
                field: "steps_per_epoch, num_envs, hidden".into(),
                value: format!("{}, {}, {:?}", self.steps_per_epoch, self.num_envs, self.hidden),
                rule: format!(
                    "the run would need about {:.1} GiB of memory, more than this machine's {:.1} GiB; lower them",
                    need / GIB,
                    have as f64 / GIB
                ),
            });
        }
        Ok(())
    }

    /// The configuration as TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self)
            .unwrap_or_else(|e| format!("# could not serialize the config: {e}\n"))
    }
}

/// Every config key with what it does and its range: `apo config` prints them beside the
/// values (a test checks that every key of the config has an entry here).
pub const KEY_DOCS: &[(&str, &str)] = &[
    ("env", "environment name (see `apo list`)"),
    ("seed", "seed of everything random in the run; 0..=9223372036854775807"),
    ("epochs", "number of epochs (paper: 200 continuous, 500 Atari); ≥ 1"),
    ("steps_per_epoch", "environment steps collected per epoch (paper: 30000); num_envs..=100000000"),
    ("num_envs", "environments stepped together, the epoch's steps split between them; 1..=65536"),
    ("normalize_obs", "normalize observations with running statistics (saved in checkpoints); true/false"),
    ("backend", "backend of the updates: \"cpu\" (NdArray) or \"wgpu\""),
    ("kernels", "where the Fisher-vector products and the value fit run: \"host\" (apo's f32 CPU kernels), \"backend\" (Burn's graph on `backend`) or \"auto\" (host with cpu, backend with wgpu)"),
    ("checkpoint_every", "write a checkpoint every this many epochs (and at the end and on interrupt); ≥ 1"),
    ("keep_checkpoint_every", "also keep every this many epochs' checkpoint as checkpoints/epoch-<N> (`apo eval --checkpoint N`); 0 = off"),
    ("hidden", "hidden layer sizes of the policy and value MLPs, tanh (paper: [64, 64]); 1..=64 layers of 1..=1048576"),
    ("init_log_std", "initial state-independent log standard deviation of Gaussian policies; [-20, 2]"),
    ("algo", "the algorithm's hyperparameters"),
    ("algo.algo", "algorithm: apo, papo, trpo, ppo, a2c (set by --algo)"),
    ("algo.gamma", "discount factor γ; [0, 1)"),
    ("algo.lambda", "GAE λ; [0, 1]"),
    ("algo.k", "probability factor k of the bound J − k·Var (APO, PAPO; paper: 7); ≥ 0"),
    ("algo.omega1", "ω1, stands for ‖μ‖∞/(1−γ²) (APO, PAPO; paper grid 0.001..0.01); ≥ 0"),
    ("algo.omega2", "ω2, stands for |H|_max when h_max = \"hyperparameter\" (APO, PAPO); ≥ 0"),
    ("algo.h_max", "where |H|_max comes from: \"hyperparameter\" (ω2) or \"estimated\" (paper's ablation Q3)"),
    ("algo.clip", "clip ε of the probability ratio (PPO, PAPO; paper: 0.2); (0, 1)"),
    ("algo.trust_region", "the trust-region step (APO, TRPO)"),
    ("algo.trust_region.max_kl", "KL radius δ (paper: 0.02); > 0"),
    ("algo.trust_region.cg_iters", "conjugate-gradient iterations; ≥ 1"),
    ("algo.trust_region.cg_damping", "damping added to the Fisher matrix, (F + damping·I)x = g; ≥ 0"),
    ("algo.trust_region.cg_residual_tol", "CG stops when the squared residual falls below this; ≥ 0"),
    ("algo.trust_region.backtrack_coeff", "backtracking coefficient ξ (paper: 0.8); (0, 1)"),
    ("algo.trust_region.backtrack_iters", "backtracking tries (paper: 100); ≥ 1"),
    ("algo.policy_update", "the policy's Adam update (PAPO, PPO, A2C)"),
    ("algo.policy_update.lr", "Adam learning rate (paper: 3e-4); > 0"),
    ("algo.policy_update.iters", "passes over the batch (paper: 80); ≥ 1"),
    ("algo.policy_update.target_kl", "stop early once the approximate KL exceeds this (paper: 0.02); > 0, optional"),
    ("algo.policy_update.minibatch_size", "minibatch size; optional (unset: full batch)"),
    ("algo.value_update", "the value network's Adam update (all algorithms)"),
    ("algo.value_update.lr", "Adam learning rate (paper: 1e-3); > 0"),
    ("algo.value_update.iters", "passes over the batch (paper: 80); ≥ 1"),
    ("algo.value_update.target_kl", "unused by the value update; optional"),
    ("algo.value_update.minibatch_size", "minibatch size; optional (unset: full batch)"),
];

fn key_doc(key: &str) -> &'static str {
    KEY_DOCS
        .iter()
        .find(|(k, _)| *k == key)
        .map_or("", |(_, d)| d)
}

impl RunConfig {
    /// The configuration as TOML with every key's meaning and range as a comment above it
    /// (optional keys that are unset appear commented out).
    pub fn documented_toml(&self) -> String {
        let mut out = String::new();
        write_documented(&to_table(self), "", &mut out);
        out
    }
}

fn write_documented(table: &toml::Table, prefix: &str, out: &mut String) {
    use std::fmt::Write as _;
    let dotted = |k: &str| {
        if prefix.is_empty() {
            k.to_string()
        } else {
            format!("{prefix}.{k}")
        }
    };
    for (k, v) in table.iter().filter(|(_, v)| !v.is_table()) {
        let _ = writeln!(out, "# {}\n{k} = {v}", key_doc(&dotted(k)));
    }
    for optional in OPTIONAL_KEYS
        .iter()
        .filter_map(|o| o.strip_prefix(&format!("{prefix}.")))
    {
        if !optional.contains('.') && !table.contains_key(optional) {
            let _ = writeln!(out, "# {}\n# {optional} =", key_doc(&dotted(optional)));
        }
    }
    for (k, v) in table.iter() {
        if let toml::Value::Table(t) = v {
            let key = dotted(k);
            let _ = writeln!(out, "\n# {}\n[{key}]", key_doc(&key));
            write_documented(t, &key, out);
        }
    }
}

/// Upper bounds of the size keys (far above the paper's; they keep arithmetic in range).
const MAX_STEPS_PER_EPOCH: usize = 100_000_000;
const MAX_NUM_ENVS: usize = 65_536;
const MAX_LAYERS: usize = 64;
const MAX_WIDTH: usize = 1 << 20;
const GIB: f64 = (1u64 << 30) as f64;
/// Assumed memory where `/proc/meminfo` cannot be read.
const MEMORY_WITHOUT_PROC: u64 = 64 << 30;

/// An upper estimate, in bytes, of what a run of `config` allocates on an environment with
/// `observation_dim` observations and `action`:
///
/// - per network parameter, 128 bytes: the Autodiff and host copies, Adam's two moments,
///   gradients, the f64 flat vectors of the trust-region step and the checkpoint records;
/// - per sample of the epoch, the stored transition three times (rollout buffer, batch, backend
///   tensors; f32) and 48 bytes per hidden unit (activations, their gradients and the second
///   backward pass of the Hessian-vector product);
/// - per environment, 1 MiB (MuJoCo's model data and arena).
pub fn memory_estimate(config: &RunConfig, observation_dim: usize, action: ActionKind) -> f64 {
    let dist = match action {
        ActionKind::Continuous { dim } => 2 * dim,
        ActionKind::Discrete { n } => n,
    } as f64;
    let layers = |output: f64| {
        let mut sizes = vec![observation_dim as f64];
        sizes.extend(config.hidden.iter().map(|&h| h as f64));
        sizes.push(output);
        sizes.windows(2).map(|w| w[0] * w[1] + w[1]).sum::<f64>()
    };
    let params = layers(dist) + layers(1.0);
    let samples =
        config.steps_per_epoch.div_ceil(config.num_envs.max(1)) as f64 * config.num_envs as f64;
    let transition = (observation_dim as f64 + action.width() as f64 + dist + 5.0) * 4.0 * 3.0;
    let activations = config.hidden.iter().sum::<usize>() as f64 * 48.0;
    params * 128.0
        + samples * (transition + activations)
        + config.num_envs as f64 * (1u64 << 20) as f64
}

/// This machine's physical memory in bytes (`MemTotal` of `/proc/meminfo`).
fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
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
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
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
    ConfigFileError::UnknownKey {
        key: key.to_string(),
        suggestion,
    }
}

/// Merges `layer` into `base`, rejecting keys `base` does not have.
fn merge(base: &mut toml::Table, layer: toml::Table, prefix: &str) -> Result<(), ConfigFileError> {
    let mut keys = Vec::new();
    all_keys(base, prefix, &mut keys);
    for (k, v) in layer {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
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
    let (last, parents) = parts
        .split_last()
        .ok_or_else(|| ConfigFileError::BadSet(key.to_string()))?;
    let mut cursor = &mut layer;
    for p in parents {
        cursor = match cursor
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
        {
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
        let sets = vec![
            "algo.gamma=0.95".to_string(),
            "hidden=[32, 16]".to_string(),
            "env=CartPole-v1".into(),
        ];
        let c = RunConfig::build(Algorithm::Ppo, "Pendulum-v1", None, &sets).expect("valid");
        assert_eq!(c.algo.gamma, 0.95);
        assert_eq!(c.hidden, vec![32, 16]);
        assert_eq!(c.env, "CartPole-v1");

        let err =
            RunConfig::build(Algorithm::Apo, "x", None, &["algo.gama=0.9".into()]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "unknown config key `algo.gama`; did you mean `algo.gamma`?"
        );

        let err =
            RunConfig::build(Algorithm::Apo, "x", None, &["algo.k=\"seven\"".into()]).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("config key `algo.k`: invalid type"),
            "{err}"
        );

        let err =
            RunConfig::build(Algorithm::Apo, "x", None, &["algo.gamma=1.0".into()]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "invalid `algo.gamma` = 1: must be in [0, 1)"
        );

        let c = RunConfig::build(
            Algorithm::Ppo,
            "x",
            None,
            &["algo.policy_update.minibatch_size=64".into()],
        )
        .expect("optional key");
        assert_eq!(c.algo.policy_update.minibatch_size, Some(64));
    }

    #[test]
    fn shipped_configs_are_the_paper_defaults() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs");
        for algo in Algorithm::ALL {
            let file = dir.join(format!("{algo}.toml"));
            let c = RunConfig::build(algo, "x", Some(&file), &[])
                .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
            assert_eq!(c, RunConfig::defaults(algo, "x"), "{}", file.display());
        }
    }

    #[test]
    fn every_key_is_documented_and_the_documented_toml_parses_back() {
        let mut c = RunConfig::defaults(Algorithm::Apo, "Hopper");
        c.algo.policy_update.minibatch_size = Some(64);
        let mut keys = Vec::new();
        all_keys(&to_table(&c), "", &mut keys);
        keys.extend(OPTIONAL_KEYS.iter().map(|k| k.to_string()));
        for key in &keys {
            assert!(
                !key_doc(key).is_empty(),
                "config key `{key}` has no entry in KEY_DOCS"
            );
        }
        for (key, _) in KEY_DOCS {
            assert!(
                keys.iter().any(|k| k == key),
                "KEY_DOCS documents `{key}`, which is not a config key"
            );
        }
        let text = c.documented_toml();
        assert!(
            text.contains("# discount factor γ; [0, 1)\ngamma = 0.99"),
            "{text}"
        );
        assert!(
            text.contains("# algo.policy_update.target_kl") || text.contains("target_kl = 0.02"),
            "{text}"
        );
        assert!(
            text.contains("# minibatch_size =\n"),
            "unset optional keys appear commented out: {text}"
        );
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("documented.toml");
        std::fs::write(&path, &text).expect("write");
        assert_eq!(
            RunConfig::load(&path).expect("the documented config loads"),
            c
        );
    }

    #[test]
    fn sizes_are_bounded_and_memory_is_estimated_before_allocating() {
        let err = RunConfig::build(
            Algorithm::Apo,
            "x",
            None,
            &["steps_per_epoch=1000000000000".into()],
        )
        .unwrap_err();
        assert!(
            err.to_string()
                .starts_with("invalid `steps_per_epoch` = 1000000000000: must be ≤"),
            "{err}"
        );
        let err = RunConfig::build(Algorithm::Apo, "x", None, &["hidden=[1000000000]".into()])
            .unwrap_err();
        assert!(err.to_string().contains("`hidden`"), "{err}");
        let err =
            RunConfig::build(Algorithm::Apo, "x", None, &["init_log_std=1e30".into()]).unwrap_err();
        assert!(
            err.to_string()
                .contains("`init_log_std` = 1000000000000000000000000000000"),
            "{err}"
        );
        let action = ActionKind::Continuous { dim: 3 };
        let paper = RunConfig::defaults(Algorithm::Apo, "Hopper");
        // the paper's Hopper run: ~10 k parameters, 30 000 samples of 11 + 3 + 6 floats
        let estimate = memory_estimate(&paper, 11, action);
        assert!(
            estimate > 30_000.0 * 128.0 * 48.0 && estimate < 1e9,
            "{estimate}"
        );
        paper
            .check_memory(11, action)
            .expect("the paper's Hopper run fits");
        let wide = RunConfig {
            hidden: vec![1 << 20, 1 << 20],
            ..paper
        };
        let err = wide.check_memory(11, action).unwrap_err();
        assert!(err.to_string().contains("GiB of memory"), "{err}");
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
