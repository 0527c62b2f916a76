//! Run configuration: TOML files, `--set key=value` overrides, validation.
//!
//! A run's configuration is built in layers: the paper's defaults for the algorithm, then
//! the `--config` file, then `--set` overrides and the dedicated flags (`--env`, `--seed`,
//! `--epochs`, …). Every key is checked: an unknown key is rejected with its dotted path
//! and the closest known key, a value of the wrong type names the key and the expected
//! type, and out-of-range values name the field and the rule.

use std::collections::BTreeMap;
use std::path::Path;

use crate::backend::{BackendKind, KernelsKind};
use crate::TrainConfig;
use apo_core::{ActionKind, AlgoConfig, Algorithm};
use serde::Serialize;

/// Everything a training run needs; written to `config.toml` in the run directory: the
/// training loop's settings (flat, as in the file) plus where the updates run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunConfig {
    /// The training loop's settings.
    #[serde(flatten)]
    pub train: TrainConfig,
    /// Backend of the updates.
    pub backend: BackendKind,
    /// Where the Fisher-vector products, the proximal policy steps and the value fit run.
    pub kernels: KernelsKind,
    /// Record a video of one evaluation episode every this many epochs
    /// (`videos/epoch-<N>.gif`); 0: never.
    pub render_every: usize,
}

/// A configuration error; the message names the key.
#[derive(Debug, thiserror::Error)]
pub enum ConfigFileError {
    /// The file could not be read (a missing file, a folder, a pipe, a file too large).
    #[error("{0}")]
    Read(String),
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
    /// A key of another algorithm's section.
    #[error("`{key}` is in the section of {section}, but the run's algorithm is {chosen}: a config holds the \
             section of its own algorithm only (choose {section} with --algo {section}, or write [algo.{chosen}])")]
    OtherAlgorithm {
        /// Dotted path of the key.
        key: String,
        /// The algorithm whose section it is.
        section: Algorithm,
        /// The run's algorithm.
        chosen: Algorithm,
    },
    /// A setting that the run's algorithm does not have, but others do.
    #[error("unknown config key `{key}`: {chosen} has no setting `{setting}` (it is a setting of {})",
            owners.iter().map(|a| a.name()).collect::<Vec<_>>().join(", "))]
    NotOfAlgorithm {
        /// Dotted path of the key.
        key: String,
        /// The key inside the algorithm's section.
        setting: String,
        /// The run's algorithm.
        chosen: Algorithm,
        /// The algorithms that have it.
        owners: Vec<Algorithm>,
    },
    /// A config without exactly one algorithm section.
    #[error("config {origin} {message}")]
    AlgorithmSection {
        /// Where the config came from.
        origin: String,
        /// What is wrong.
        message: String,
    },
    /// A malformed `--set` argument.
    #[error("--set expects key=value, got `{0}`")]
    BadSet(String),
    /// A value out of range.
    #[error(transparent)]
    Range(#[from] apo_core::ConfigError),
    /// An error of a config file's contents, with the file named.
    #[error("config {path}: {error}")]
    InFile {
        /// The file.
        path: String,
        /// What is wrong in it.
        error: Box<ConfigFileError>,
    },
}

impl ConfigFileError {
    /// The error with the config file `path` named, unless it names a file already.
    fn in_file(self, path: &Path) -> Self {
        match self {
            Self::Read(_)
            | Self::Parse { .. }
            | Self::AlgorithmSection { .. }
            | Self::BadSet(_)
            | Self::InFile { .. } => self,
            error => Self::InFile {
                path: path.display().to_string(),
                error: Box::new(error),
            },
        }
    }
}

/// A named set of settings over the defaults and a config file: defaults, then `--config`,
/// then the preset, then `--set`. Each of its settings is also a config key of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Preset {
    /// The paper's published code where it differs from our defaults (docs/algorithms.md,
    /// "The paper preset"): conjugate gradient of 100 iterations without damping, stopping
    /// at a residual norm of 1e-8, and `1e-8` added to `xᵀFx`; raw Gaussian actions; A2C's
    /// single policy step; on the Gym MuJoCo and the hand tasks, no bootstrap at the time limit
    /// and every episode reset with the run's seed.
    Paper,
    /// APO and PAPO with the recommended variant (docs/algorithms.md, "The robust preset"): the
    /// penalty in the advantages' units (scale-free), min_J_sq's switch off, one ω for every
    /// task. Other algorithms are unchanged.
    Robust,
}

/// The robust preset's ω1 and ω2, in the advantages' units (docs/results/variants.md).
pub const ROBUST_OMEGA: (f64, f64) = (0.01, 0.005);

impl Preset {
    /// The preset's settings for a run of `algo` on the environment `env`, as `(key, value)`
    /// with `algo.<key>` meaning the run's algorithm section; keys the algorithm does not have
    /// (a proximal method's `trust_region`) are left out.
    pub fn settings(self, algo: Algorithm, env: &str) -> Vec<(&'static str, toml::Value)> {
        use toml::Value::{Boolean, Float, Integer, String as Text};
        match self {
            Preset::Paper => {
                // The Gym MuJoCo tasks and Gymnasium-Robotics' hands: the reference ran both
                // through the same Gymnasium loop.
                let gymnasium = apo_envs::registry::spec(env)
                    .is_ok_and(|spec| matches!(&*spec.family, "mujoco" | "hand"));
                let mut settings = vec![
                    ("algo.trust_region.cg_iters", Integer(100)),
                    ("algo.trust_region.cg_damping", Float(0.0)),
                    // the reference stops when the residual norm is below 1e-8
                    ("algo.trust_region.cg_residual_tol", Float(1e-16)),
                    ("algo.trust_region.step_epsilon", Float(1e-8)),
                    ("actions", Text("raw".into())),
                ];
                if algo == Algorithm::A2c {
                    settings.push(("algo.policy_update.iters", Integer(1)));
                }
                if gymnasium {
                    settings.push(("bootstrap_time_limit", Boolean(false)));
                    settings.push(("episode_reset", Text("run_seed".into())));
                }
                settings
            }
            Preset::Robust if matches!(algo, Algorithm::Apo | Algorithm::Papo) => vec![
                ("algo.penalty_units", Text("advantage".into())),
                ("algo.switch", Text("off".into())),
                ("algo.omega1", Float(ROBUST_OMEGA.0)),
                ("algo.omega2", Float(ROBUST_OMEGA.1)),
            ],
            Preset::Robust => Vec::new(),
        }
    }
}

impl RunConfig {
    /// The paper's defaults for `algo` on `env`, on the cpu backend.
    pub fn defaults(algo: Algorithm, env: &str) -> Self {
        Self {
            train: TrainConfig::defaults(algo, env),
            backend: BackendKind::Cpu,
            kernels: KernelsKind::Auto,
            render_every: 0,
        }
    }

    /// Builds a configuration: defaults for `algo`, then the TOML `file` if any (its algorithm
    /// section must be `algo`'s), then each `key=value` of `sets` (values in TOML syntax; a bare
    /// word is taken as a string; `algo.<key>` is short for `algo.<name>.<key>`).
    pub fn build(
        algo: Algorithm,
        env: &str,
        file: Option<&Path>,
        sets: &[String],
    ) -> Result<Self, ConfigFileError> {
        Self::build_with_preset(algo, env, None, file, sets)
    }

    /// [`RunConfig::build`] with `preset`'s settings layered over `file`, under `sets`.
    pub fn build_with_preset(
        algo: Algorithm,
        env: &str,
        preset: Option<Preset>,
        file: Option<&Path>,
        sets: &[String],
    ) -> Result<Self, ConfigFileError> {
        let mut doc = to_table(&Self::defaults(algo, env));
        if let Some(path) = file {
            let table = migrate_legacy(read_table(path)?);
            if has_several_sections(&table) {
                section_algorithm(&table, &path.display().to_string())?;
            }
            merge(&mut doc, table, "").map_err(|e| e.in_file(path))?;
        }
        for (key, value) in preset.map(|p| p.settings(algo, env)).unwrap_or_default() {
            let key = in_section(key, algo);
            if has_path(&doc, &key) {
                set_path(&mut doc, &key, value)?;
            }
        }
        for set in sets {
            let (key, value) = set
                .split_once('=')
                .ok_or_else(|| ConfigFileError::BadSet(set.clone()))?;
            let path = in_section(key.trim(), algo);
            let value = parse_value(value.trim()).map_err(|message| ConfigFileError::Type {
                key: path.clone(),
                message,
            })?;
            set_path(&mut doc, &path, value)?;
        }
        let config = Self::from_table(doc)?;
        config.validate()?;
        Ok(config)
    }

    /// Reads a configuration written by a run (`config.toml`), checking every key; every
    /// error names the file.
    pub fn load(path: &Path) -> Result<Self, ConfigFileError> {
        let load = || {
            let table = migrate_legacy(read_table(path)?);
            let algo = section_algorithm(&table, &path.display().to_string())?;
            let mut doc = to_table(&Self::defaults(algo, ""));
            merge(&mut doc, table, "")?;
            let config = Self::from_table(doc)?;
            config.validate()?;
            Ok(config)
        };
        load().map_err(|e: ConfigFileError| e.in_file(path))
    }

    fn from_table(mut doc: toml::Table) -> Result<Self, ConfigFileError> {
        fn field<T: serde::de::DeserializeOwned>(
            doc: &mut toml::Table,
            key: &str,
        ) -> Result<T, ConfigFileError> {
            let value = doc.remove(key).ok_or_else(|| ConfigFileError::Type {
                key: key.to_string(),
                message: "missing".to_string(),
            })?;
            value
                .try_into()
                .map_err(|e: toml::de::Error| ConfigFileError::Type {
                    key: key.to_string(),
                    message: e.message().to_string(),
                })
        }
        let backend = field(&mut doc, "backend")?;
        let kernels = field(&mut doc, "kernels")?;
        let render_every = field(&mut doc, "render_every")?;
        // the algorithm of the one section `algo.<name>`: serde's path leaves its name out
        let algo = match doc.get("algo") {
            Some(toml::Value::Table(t)) if t.len() == 1 => {
                t.keys().next().and_then(|k| k.parse::<Algorithm>().ok())
            }
            _ => None,
        };
        let train = serde_path_to_error::deserialize(toml::Value::Table(doc)).map_err(|e| {
            let mut key = e.path().to_string();
            if let (Some(algo), Some(inner)) = (algo, key.strip_prefix("algo.")) {
                if !inner.starts_with(&format!("{algo}.")) {
                    key = format!("algo.{algo}.{inner}");
                }
            }
            let doc = algo.map_or_else(String::new, |algo| {
                let setting = key.split('[').next().unwrap_or(&key);
                key_doc(setting, &Self::defaults(algo, "").train.algo)
            });
            ConfigFileError::Type {
                message: explain_type_error(&e.into_inner().to_string(), &doc),
                key,
            }
        })?;
        Ok(Self {
            train,
            backend,
            kernels,
            render_every,
        })
    }

    /// Checks the ranges of every field.
    pub fn validate(&self) -> Result<(), apo_core::ConfigError> {
        if self.render_every > crate::config::MAX_EPOCHS {
            return Err(apo_core::ConfigError {
                field: "render_every".into(),
                value: self.render_every.to_string(),
                rule: format!("must be ≤ {}", crate::config::MAX_EPOCHS),
            });
        }
        self.train.validate()
    }

    /// Checks that a run of this configuration on an environment with `observation_dim`
    /// observations and `action` fits in the memory this process may take ([`memory_estimate`], [`crate::input::memory_limit`]), before
    /// anything is allocated or created; the error names the keys that size it.
    pub fn check_memory(
        &self,
        observation_dim: usize,
        action: ActionKind,
    ) -> Result<(), apo_core::ConfigError> {
        let need = memory_estimate(self, observation_dim, action, self.env_bytes());
        let (have, limit) = crate::input::memory_limit();
        if need > have as f64 {
            return Err(apo_core::ConfigError {
                field: "steps_per_epoch, num_envs, hidden".into(),
                value: format!(
                    "{}, {}, {:?}",
                    self.train.steps_per_epoch, self.train.num_envs, self.train.hidden
                ),
                rule: format!(
                    "the run would need about {:.1} GiB of memory, more than {limit}; lower them",
                    need / GIB,
                ),
            });
        }
        Ok(())
    }

    /// Every value of the configuration that can change what a run learns, by dotted key
    /// (`env`, `algo.papo.omega1`, …) — every key but [`RESUMABLE_KEYS`] — as TOML text. A
    /// checkpoint records it, and a run whose `config.toml` no longer gives the same values is
    /// refused by `eval`, `render`, `train --resume` and `report`.
    pub fn learned_with(&self) -> BTreeMap<String, String> {
        let mut values = BTreeMap::new();
        if let Ok(toml::Value::Table(table)) = toml::Value::try_from(self) {
            flatten("", &toml::Value::Table(table), &mut values);
        }
        values.retain(|key, _| !RESUMABLE_KEYS.contains(&key.as_str()));
        values
    }

    /// The configuration as TOML text.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self)
            .unwrap_or_else(|e| format!("# could not serialize the config: {e}\n"))
    }
}

/// The keys that cannot change what a run learns — the epoch target, the checkpoint and
/// evaluation cadence, videos, and the pipelined schedule (bit-identical to the sequential
/// one): the only ones a run's `config.toml` may change between its checkpoint and a resume,
/// an evaluation or a report.
pub const RESUMABLE_KEYS: &[&str] = &[
    "epochs",
    "checkpoint_every",
    "keep_checkpoint_every",
    "eval_every",
    "eval_episodes",
    "eval_deterministic",
    "eval_best",
    "render_every",
    "pipeline",
];

/// `value` flattened into `out` by dotted key under `prefix`; arrays and scalars are leaves,
/// written as TOML text.
fn flatten(prefix: &str, value: &toml::Value, out: &mut BTreeMap<String, String>) {
    match value {
        toml::Value::Table(table) => {
            for (key, value) in table {
                let key = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                flatten(&key, value, out);
            }
        }
        leaf => {
            out.insert(prefix.to_string(), leaf.to_string());
        }
    }
}

/// The run's keys outside the algorithm's section with what they do and their range (the keys
/// of `[algo.<name>]` are documented by the algorithm's module, `Settings::key_docs`): `apo
/// config` prints them beside the values (a test checks that every key has an entry).
pub const KEY_DOCS: &[(&str, &str)] = &[
    ("env", "environment name (see `apo list`)"),
    ("seed", "seed of everything random in the run; 0..=9223372036854775807"),
    ("epochs", "number of epochs (paper: 200 continuous, 500 Atari); 1..=1000000000"),
    ("steps_per_epoch", "environment steps collected per epoch (paper: 30000); num_envs..=100000000"),
    ("num_envs", "environments stepped together, the epoch's steps split between them; 1..=65536"),
    ("normalize_obs", "normalize observations with running statistics (saved in checkpoints); true/false"),
    ("backend", "backend of the updates: \"cpu\" (NdArray) or \"wgpu\""),
    ("kernels", "where the Fisher-vector products, the proximal policy steps and the value fit run: \"host\" (apo's f32 CPU kernels), \"backend\" (Burn's graph on `backend`) or \"auto\" (host with cpu, backend with wgpu)"),
    ("checkpoint_every", "write a checkpoint every this many epochs (and at the end and on interrupt); 1..=1000000000"),
    ("keep_checkpoint_every", "also keep every this many epochs' checkpoint as checkpoints/epoch-<N> (`apo eval --checkpoint N`); 0 = off; 0..=1000000000"),
    ("hidden", "hidden layer sizes of the policy and value MLPs, tanh (paper: [64, 64]); 1..=64 layers of 1..=1048576"),
    ("init_log_std", "initial state-independent log standard deviation of Gaussian policies; [-20, 2]"),
    ("bootstrap_time_limit", "bootstrap episodes cut by the time limit from V(final observation); false: from 0, as the paper's code on Gym MuJoCo; true/false"),
    ("actions", "how Gaussian actions reach the environment: \"rescale\" (policy acts in [-1, 1], mapped to the box and clipped) or \"raw\" (unscaled, unclipped, as the paper's code)"),
    ("episode_reset", "how episodes start: \"epoch\" (each epoch reseeds from the run's seed, later episodes continue the stream) or \"run_seed\" (every episode reset with the run's seed, as the paper's code on Gym MuJoCo and the hands)"),
    ("max_episode_steps", "truncate episodes after this many steps (the paper's maximum trajectory length, 1000 on every suite); 0 = the environment's registered limit (`apo list`); 0..=1000000000"),
    ("physics", "the physics of MuJoCo environments: \"mujoco2\" (MuJoCo 2.2.2, Debian's libmujoco-dev) or \"mujoco3\" (MuJoCo 3.17 through mujoco-rs; a build with --features mujoco3, docs/mujoco.md)"),
    ("eval_every", "evaluate the policy every this many epochs on its own environment and seeds (eval_* columns of progress.csv; training is unchanged); 0 = never; 0..=1000000000"),
    ("eval_episodes", "episodes of each evaluation; 1..=1000000"),
    ("eval_deterministic", "evaluate with the most likely action (a Gaussian's mean) instead of sampling; true/false"),
    ("eval_best", "the evaluation statistic that picks checkpoints/best (`apo eval --checkpoint best`): \"mean\", \"worst\" or \"cvar10\""),
    ("render_every", "record a video of one evaluation episode every this many epochs, videos/epoch-<N>.gif, also in TensorBoard's Images tab (its own environment and seeds: training is unchanged; `apo render` for more); 0 = never; 0..=1000000000"),
    ("pipeline", "overlap each epoch's value fit with the next epoch's rollout (bit-identical results; docs/architecture.md); true/false"),
    ("algo", "the algorithm's settings: one section, [algo.<name>], for the algorithm of the run"),
];

/// What `key` (a dotted path) does, for a run of algorithm `algo`; "" for no such key.
fn key_doc(key: &str, algo: &AlgoConfig) -> String {
    let section = format!("algo.{}", algo.algorithm());
    if key == section {
        return format!("{}: its settings", algo.algorithm().about());
    }
    if let Some(inner) = key.strip_prefix(&format!("{section}.")) {
        return algo
            .settings()
            .key_docs()
            .into_iter()
            .find(|(k, _)| k == inner)
            .map_or_else(String::new, |(_, d)| d.to_string());
    }
    KEY_DOCS
        .iter()
        .find(|(k, _)| *k == key)
        .map_or_else(String::new, |(_, d)| d.to_string())
}

impl RunConfig {
    /// The configuration as TOML with every key's meaning and range as a comment above it
    /// (optional keys that are unset appear commented out).
    pub fn documented_toml(&self) -> String {
        let mut out = String::new();
        write_documented(&to_table(self), "", &self.train.algo, &mut out);
        out
    }
}

fn write_documented(table: &toml::Table, prefix: &str, algo: &AlgoConfig, out: &mut String) {
    use std::fmt::Write as _;
    let dotted = |k: &str| {
        if prefix.is_empty() {
            k.to_string()
        } else {
            format!("{prefix}.{k}")
        }
    };
    for (k, v) in table.iter().filter(|(_, v)| !v.is_table()) {
        let _ = writeln!(out, "# {}\n{k} = {v}", key_doc(&dotted(k), algo));
    }
    for optional in OPTIONAL_FIELDS.iter().filter(|o| is_optional(&dotted(o))) {
        if !table.contains_key(*optional) {
            let _ = writeln!(
                out,
                "# {}\n# {optional} =",
                key_doc(&dotted(optional), algo)
            );
        }
    }
    for (k, v) in table.iter() {
        if let toml::Value::Table(t) = v {
            let key = dotted(k);
            let _ = writeln!(out, "\n# {}\n[{key}]", key_doc(&key, algo));
            write_documented(t, &key, algo, out);
        }
    }
}

const GIB: f64 = (1u64 << 30) as f64;

/// The memory one environment is assumed to take when a run has few of them: 8 MiB, above
/// every task's measured figure (Humanoid 2.3 MiB, the hands 3.6, Goal_Ant 4.3).
const ENV_BYTES_BOUND: f64 = (8u64 << 20) as f64;

/// Runs with more environments than this measure what one of theirs takes.
const MEASURE_ENVS_ABOVE: usize = 128;

impl RunConfig {
    /// The memory one environment of the run takes, in bytes: `ENV_BYTES_BOUND` for a run of
    /// at most `MEASURE_ENVS_ABOVE` environments; for more, measured: the growth of this
    /// process's resident memory per environment when two more are made, reset and stepped 20
    /// times after a first one (which pays for loading the library), × 1.25. MuJoCo's model and
    /// `mjData` arena are most of it; never below 1 MiB, since the allocator can reuse memory.
    pub fn env_bytes(&self) -> f64 {
        if self.train.num_envs <= MEASURE_ENVS_ABOVE {
            return ENV_BYTES_BOUND;
        }
        let options = self.train.make_options();
        let exercised = || -> Option<Box<dyn apo_envs::Env>> {
            let mut env = apo_envs::make_with(&self.train.env, &options).ok()?;
            let mut obs = vec![0.0f32; env.observation_space().flat_dim()];
            let zeros = vec![0.0f32; env.action_space().flat_dim()];
            env.reset(Some(0), &mut obs);
            for _ in 0..20 {
                let action = match env.action_space() {
                    apo_envs::Space::Discrete { .. } => apo_envs::Action::Discrete(0),
                    apo_envs::Space::Box { .. } => apo_envs::Action::Continuous(&zeros),
                };
                let t = env.step(action, &mut obs);
                if t.terminated || t.truncated {
                    env.reset(Some(0), &mut obs);
                }
            }
            Some(env)
        };
        let measured = (|| {
            let _warm = exercised()?;
            let before = crate::input::resident_memory()?;
            let _more = [exercised()?, exercised()?];
            let after = crate::input::resident_memory()?;
            Some(after.saturating_sub(before) as f64 / 2.0 * 1.25)
        })();
        measured.map_or(ENV_BYTES_BOUND, |b| b.max((1u64 << 20) as f64))
    }
}

/// An upper estimate, in bytes, of what a run of `config` allocates on an environment with
/// `observation_dim` observations and `action`:
///
/// - per network parameter, 128 bytes: the Autodiff and host copies, Adam's two moments,
///   gradients, the f64 flat vectors of the trust-region step and the checkpoint records;
/// - per sample of the epoch, the stored transition three times (rollout buffer, batch, backend
///   tensors; f32) and 48 bytes per hidden unit (activations, their gradients and the second
///   backward pass of the Hessian-vector product);
/// - per environment, `env_bytes` ([`RunConfig::env_bytes`]: MuJoCo's model, data and arena).
pub fn memory_estimate(
    config: &RunConfig,
    observation_dim: usize,
    action: ActionKind,
    env_bytes: f64,
) -> f64 {
    let dist = action.dist_width() as f64;
    let layers = |output: f64| {
        let mut sizes = vec![observation_dim as f64];
        sizes.extend(config.train.hidden.iter().map(|&h| h as f64));
        sizes.push(output);
        sizes.windows(2).map(|w| w[0] * w[1] + w[1]).sum::<f64>()
    };
    let params = layers(dist) + layers(1.0);
    let samples = config
        .train
        .steps_per_epoch
        .div_ceil(config.train.num_envs.max(1)) as f64
        * config.train.num_envs as f64;
    let transition = (observation_dim as f64 + action.width() as f64 + dist + 5.0) * 4.0 * 3.0;
    let activations = config.train.hidden.iter().sum::<usize>() as f64 * 48.0;
    params * 128.0 + samples * (transition + activations) + config.train.num_envs as f64 * env_bytes
}

fn to_table<T: Serialize>(value: &T) -> toml::Table {
    match toml::Value::try_from(value) {
        Ok(toml::Value::Table(t)) => t,
        _ => toml::Table::new(),
    }
}

/// Fields of an algorithm's Adam updates (`algo.<name>.<x>_update`) that are optional (absent
/// means `None`) and so can be missing from the defaults' table.
const OPTIONAL_FIELDS: &[&str] = &["target_kl", "minibatch_size"];

/// Whether `key` is an optional field of an update table of an algorithm's section.
fn is_optional(key: &str) -> bool {
    let parts: Vec<&str> = key.split('.').collect();
    matches!(parts.as_slice(), ["algo", _, update, field]
        if update.ends_with("_update") && OPTIONAL_FIELDS.contains(field))
}

/// The section of every algorithm's defaults, as TOML tables.
fn algorithm_sections() -> Vec<(Algorithm, toml::Table)> {
    Algorithm::ALL
        .iter()
        .map(|&a| {
            let section = match to_table(&AlgoConfig::paper_defaults(a)).remove(a.name()) {
                Some(toml::Value::Table(t)) => t,
                _ => toml::Table::new(),
            };
            (a, section)
        })
        .collect()
}

/// Whether the dotted `path` names a key of `table` (or an optional update field in it).
fn has_path(table: &toml::Table, path: &str) -> bool {
    match path.split_once('.') {
        None => table.contains_key(path),
        Some((head, rest)) => match table.get(head) {
            Some(toml::Value::Table(t)) => {
                has_path(t, rest) || (head.ends_with("_update") && OPTIONAL_FIELDS.contains(&rest))
            }
            _ => false,
        },
    }
}

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
    // the run's algorithm: the one section under `algo`
    let chosen = doc_keys
        .iter()
        .filter_map(|k| {
            k.strip_prefix("algo.")?
                .split('.')
                .next()?
                .parse::<Algorithm>()
                .ok()
        })
        .next();
    let parts: Vec<&str> = key.splitn(3, '.').collect();
    if let (Some(chosen), ["algo", name, ..]) = (chosen, parts.as_slice()) {
        match name.parse::<Algorithm>() {
            Ok(other) if other != chosen => {
                return ConfigFileError::OtherAlgorithm {
                    key: key.to_string(),
                    section: other,
                    chosen,
                }
            }
            Ok(_) => {
                if let Some(inner) = parts.get(2) {
                    let owners: Vec<Algorithm> = algorithm_sections()
                        .into_iter()
                        .filter(|(_, section)| has_path(section, inner))
                        .map(|(a, _)| a)
                        .collect();
                    if !owners.is_empty() {
                        return ConfigFileError::NotOfAlgorithm {
                            key: key.to_string(),
                            setting: inner.to_string(),
                            chosen,
                            owners,
                        };
                    }
                }
            }
            Err(_) => {}
        }
    }
    if let ["algo", name] = parts.as_slice() {
        let names: Vec<&str> = Algorithm::ALL.iter().map(|a| a.name()).collect();
        return ConfigFileError::Type {
            key: key.to_string(),
            message: format!(
                "`{name}` is not an algorithm: a config's section is [algo.<name>] with one of {}",
                names.join(", ")
            ),
        };
    }
    // the closest key of the same section, by its last part (whole dotted keys share their
    // section's prefix, which would make any key of it look close)
    let (parent, last) = key.rsplit_once('.').unwrap_or(("", key));
    let suggestion = doc_keys
        .iter()
        .map(String::as_str)
        .filter_map(|k| {
            let (p, l) = k.rsplit_once('.').unwrap_or(("", k));
            (p == parent).then(|| (strsim::jaro_winkler(l, last), k))
        })
        .filter(|(score, _)| *score > 0.8)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, k)| k.to_string())
        // a setting of the algorithm given without its section (`gamma` for `algo.ppo.gamma`)
        .or_else(|| {
            let in_section = format!("algo.{}.{key}", chosen?.name());
            doc_keys.contains(&in_section).then_some(in_section)
        });
    ConfigFileError::UnknownKey {
        key: key.to_string(),
        suggestion,
    }
}

/// `key` with the shorthand `algo.<key>` expanded to `algo.<name>.<key>` for the run's
/// algorithm `algo` (keys already naming an algorithm's section are kept).
fn in_section(key: &str, algo: Algorithm) -> String {
    match key.strip_prefix("algo.") {
        Some(rest)
            if rest
                .split('.')
                .next()
                .and_then(|s| s.parse::<Algorithm>().ok())
                .is_none() =>
        {
            format!("algo.{algo}.{rest}")
        }
        _ => key.to_string(),
    }
}

/// The algorithm whose section `[algo.<name>]` a config table holds (`origin` names the table
/// in errors).
fn section_algorithm(table: &toml::Table, origin: &str) -> Result<Algorithm, ConfigFileError> {
    let names: Vec<&str> = Algorithm::ALL.iter().map(|a| a.name()).collect();
    let sections: Vec<Algorithm> = match table.get("algo") {
        Some(toml::Value::Table(algo)) => algo.keys().filter_map(|k| k.parse().ok()).collect(),
        _ => Vec::new(),
    };
    match sections.as_slice() {
        [one] => Ok(*one),
        [] => Err(ConfigFileError::AlgorithmSection {
            origin: origin.to_string(),
            message: format!(
                "has no algorithm section [algo.<name>] (one of {})",
                names.join(", ")
            ),
        }),
        several => Err(ConfigFileError::AlgorithmSection {
            origin: origin.to_string(),
            message: format!(
                "has the sections of several algorithms ({}); a config holds one",
                several
                    .iter()
                    .map(|a| a.name())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }),
    }
}

/// The algorithm of the config file `path` when it has an `[algo.<name>]` section.
pub fn file_algorithm(path: &Path) -> Result<Option<Algorithm>, ConfigFileError> {
    let table = migrate_legacy(read_table(path)?);
    match section_algorithm(&table, &path.display().to_string()) {
        Ok(algo) => Ok(Some(algo)),
        Err(e) if has_several_sections(&table) => Err(e),
        Err(_) => Ok(None),
    }
}

/// The environment of the config file `path` when it names one (its top-level `env` key, as
/// in a run's `config.toml`).
///
/// # Errors
/// When the file cannot be read or parsed, or its `env` is not a string.
pub fn file_env(path: &Path) -> Result<Option<String>, ConfigFileError> {
    match read_table(path)?.remove("env") {
        None => Ok(None),
        Some(toml::Value::String(env)) => Ok(Some(env)),
        Some(other) => Err(ConfigFileError::Type {
            key: "env".to_string(),
            message: format!(
                "expected a string (an environment name) in {}, found {other}",
                path.display()
            ),
        }),
    }
}

/// Whether `table` holds the sections of more than one algorithm.
fn has_several_sections(table: &toml::Table) -> bool {
    match table.get("algo") {
        Some(toml::Value::Table(algo)) => {
            algo.keys()
                .filter(|k| k.parse::<Algorithm>().is_ok())
                .count()
                > 1
        }
        _ => false,
    }
}

fn read_table(path: &Path) -> Result<toml::Table, ConfigFileError> {
    let text = crate::input::read_text(path, "config file", crate::input::SMALL_FILE)
        .map_err(|e| ConfigFileError::Read(format!("{e:#}")))?;
    text.parse()
        .map_err(|e: toml::de::Error| ConfigFileError::Parse {
            origin: path.display().to_string(),
            message: e.to_string(),
        })
}

/// A config of the flat format of apo ≤ 0.1's first runs (`[algo]` with `algo = "<name>"` and
/// every algorithm's keys side by side) in today's form: the keys of that algorithm moved into
/// its section `[algo.<name>]`, the others (which it ignored) dropped. Other tables are
/// returned as they are.
fn migrate_legacy(mut table: toml::Table) -> toml::Table {
    let Some(toml::Value::Table(algo)) = table.get("algo") else {
        return table;
    };
    let Some(Ok(chosen)) = algo
        .get("algo")
        .and_then(toml::Value::as_str)
        .map(str::parse::<Algorithm>)
    else {
        return table;
    };
    let defaults = algorithm_sections()
        .into_iter()
        .find(|(a, _)| *a == chosen)
        .map(|(_, t)| t)
        .unwrap_or_default();
    let section: toml::Table = algo
        .iter()
        .filter(|(k, _)| defaults.contains_key(*k))
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    let mut migrated = toml::Table::new();
    migrated.insert(chosen.name().to_string(), toml::Value::Table(section));
    table.insert("algo".to_string(), toml::Value::Table(migrated));
    table
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
            // a section and a value do not stand for each other, whichever flag or file later
            // sets the key
            (Some(toml::Value::Table(b)), v) => {
                let keys: Vec<&str> = b.keys().map(String::as_str).take(4).collect();
                return Err(ConfigFileError::Type {
                    message: format!(
                        "is a section (keys {}{}), not a value: set its keys, e.g. `{key}.{}=…`, found {}",
                        keys.join(", "),
                        if b.len() > keys.len() { ", …" } else { "" },
                        keys.first().unwrap_or(&"key"),
                        v.type_str()
                    ),
                    key,
                });
            }
            (Some(slot), toml::Value::Table(_)) => {
                return Err(ConfigFileError::Type {
                    message: format!(
                        "expected a {} (e.g. `{key} = {slot}`), found a table: `{key}` has no keys of its own",
                        slot.type_str()
                    ),
                    key,
                });
            }
            (Some(slot), v) => *slot = v,
            (None, v) if is_optional(&key) => {
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

/// Refuses a key given twice among `--set KEY=VALUE` options (`algo.k` and `algo.<name>.k`
/// are one key), as `apo sweep` refuses a grid value given twice: which one was meant?
///
/// # Errors
/// Naming the key and both options.
pub fn check_repeated_sets(sets: &[String]) -> anyhow::Result<()> {
    let mut seen: BTreeMap<String, &str> = BTreeMap::new();
    for set in sets {
        let Some((key, _)) = set.split_once('=') else {
            continue;
        };
        if let Some(first) = seen.insert(same_key(key), set) {
            anyhow::bail!("--set {first} and --set {set} set one key twice; give it once");
        }
    }
    Ok(())
}

/// The key `key` names, the same for every way of writing it: `algo.<name>.<key>` and
/// `algo.<key>` name the same key of a run's algorithm.
pub fn same_key(key: &str) -> String {
    let mut parts: Vec<&str> = key.trim().split('.').collect();
    if parts.len() > 2 && parts[0] == "algo" && parts[1].parse::<Algorithm>().is_ok() {
        parts.remove(1);
    }
    parts.join(".")
}

/// A `--set` value: TOML syntax (`0.99`, `true`, `[64, 64]`, `"x"`), or a bare string.
///
/// # Errors
/// A number TOML cannot hold (`99999999999999999999`, `1e400`), which would otherwise become
/// a string: the message gives the ranges.
pub fn parse_value(text: &str) -> Result<toml::Value, String> {
    let parsed = format!("v = {text}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"));
    // a digit-spelled float that overflowed to ±inf is out of range too (`inf` is spelled so)
    let overflowed = matches!(parsed, Some(toml::Value::Float(f)) if !f.is_finite());
    if let Some(value) = parsed.filter(|_| !(overflowed && looks_numeric(text))) {
        return Ok(value);
    }
    if text.starts_with(['[', '{']) {
        return Err(format!(
            "`{text}` is not a TOML list or table (a number in it out of range? integers are from {} to {}, floats finite)",
            i64::MIN,
            i64::MAX
        ));
    }
    let digits = text.trim_start_matches(['+', '-']);
    if digits.len() > 1 && digits.starts_with('0') && digits.as_bytes()[1].is_ascii_digit() {
        return Err(format!(
            "`{text}`: a number is written without leading zeros (TOML), e.g. `{}`",
            digits
                .trim_start_matches('0')
                .split(['.', 'e', 'E'])
                .next()
                .filter(|d| !d.is_empty())
                .unwrap_or("0")
        ));
    }
    if looks_numeric(text) {
        return Err(format!(
            "`{text}` is a number out of range: integers are from {} to {}, floats finite (at most about 1.8e308)",
            i64::MIN,
            i64::MAX
        ));
    }
    Ok(toml::Value::String(text.to_string()))
}

/// serde's type error `message` in the user's words: what was found (a number written short,
/// never 309 digits), then what the key takes (`doc`, its meaning and range).
fn explain_type_error(message: &str, doc: &str) -> String {
    let first = message.lines().next().unwrap_or(message);
    let (what, rest) = match first.strip_prefix("invalid value: ") {
        Some(rest) => ("out of range", Some(rest)),
        None => ("wrong kind of value", first.strip_prefix("invalid type: ")),
    };
    let text = match rest.and_then(|m| m.split_once(", expected ")) {
        Some((found, _)) => {
            let quoted = found
                .split_once('`')
                .and_then(|(_, rest)| rest.rsplit_once('`'))
                .map(|(v, _)| v);
            let found = match (found.split_once(' ').map(|(k, _)| k), quoted) {
                (Some("floating"), Some(v)) => match v.parse::<f64>() {
                    // an integer key given `1e3` or `3.0`
                    Ok(f) if f.fract() == 0.0 && f.abs() < 1e15 => format!(
                        "the decimal number {}, where a whole number is written without a point or exponent, `{}`",
                        apo_core::shown(f),
                        f as i64
                    ),
                    Ok(f) => format!("the decimal number {}", apo_core::shown(f)),
                    Err(_) => "a decimal number".to_string(),
                },
                (Some("integer"), Some(v)) => format!("the whole number {v}"),
                (Some("string"), _) => format!("the text {}", found.trim_start_matches("string ")),
                (Some("boolean"), Some(v)) => format!("the value {v}"),
                _ if found.starts_with("unit") => "a value of another kind".to_string(),
                _ => found.to_string(),
            };
            format!("{what}: found {found}")
        }
        None => first.to_string(),
    };
    if doc.is_empty() {
        text
    } else {
        format!("{text}; it takes: {doc}")
    }
}

/// Whether `text` is written as a number: a sign, digits (with `_`), a fraction, an exponent.
fn looks_numeric(text: &str) -> bool {
    let body = text.trim_start_matches(['+', '-']);
    let (mantissa, exponent) = match body.split_once(['e', 'E']) {
        Some((m, e)) => (m, Some(e.trim_start_matches(['+', '-']))),
        None => (body, None),
    };
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit() || b == b'_');
    let mantissa_ok = match mantissa.split_once('.') {
        Some((whole, fraction)) => {
            (digits(whole) || whole.is_empty())
                && (digits(fraction) || fraction.is_empty())
                && !(whole.is_empty() && fraction.is_empty())
        }
        None => digits(mantissa),
    };
    mantissa_ok && exponent.is_none_or(digits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_number_toml_cannot_hold_is_an_error_naming_the_ranges_not_a_string() {
        for text in [
            "99999999999999999999",
            "-99999999999999999999",
            "1e400",
            "-1.5e999",
        ] {
            let err = parse_value(text).expect_err(text);
            assert!(
                err.contains(text)
                    && err.contains("out of range")
                    && err.contains("9223372036854775807"),
                "{err}"
            );
        }
        assert_eq!(parse_value("42"), Ok(toml::Value::Integer(42)));
        assert_eq!(parse_value("1e3"), Ok(toml::Value::Float(1000.0)));
        for word in ["Walker2d-v4", "e5", "1.2.3", "nope", "-"] {
            assert_eq!(
                parse_value(word),
                Ok(toml::Value::String(word.into())),
                "{word}"
            );
        }
        let err = RunConfig::build_with_preset(
            Algorithm::Apo,
            "CartPole-v1",
            None,
            None,
            &["steps_per_epoch=99999999999999999999".to_string()],
        )
        .expect_err("out of range")
        .to_string();
        assert!(
            err.contains("steps_per_epoch") && err.contains("out of range"),
            "{err}"
        );
    }

    fn common(c: &RunConfig) -> apo_core::algorithm::Common {
        c.train.algo.common()
    }

    #[test]
    fn robust_preset_changes_apo_and_papo_only() {
        use apo_core::objective::{HMax, Objective, PenaltyUnits, Switch};
        let build = |algo, preset| {
            RunConfig::build_with_preset(algo, "Hopper-v4", preset, None, &[]).expect("valid")
        };
        for algo in [Algorithm::Apo, Algorithm::Papo] {
            let params = match build(algo, Some(Preset::Robust)).train.algo.objective() {
                Objective::Apo(p) | Objective::Papo { params: p, .. } => p,
                other => panic!("{algo}: {other:?}"),
            };
            assert_eq!(params.units, PenaltyUnits::Advantage, "{algo}");
            assert_eq!(params.switch, Switch::Off, "{algo}");
            assert_eq!(params.omega1, 0.01, "{algo}");
            assert_eq!(params.h_max, HMax::Fixed(0.005), "{algo}");
            // the rest is the defaults: k and γ as the paper's
            assert_eq!((params.k, params.gamma), (7.0, 0.99), "{algo}");
        }
        for algo in [Algorithm::Trpo, Algorithm::Ppo, Algorithm::A2c] {
            assert_eq!(
                build(algo, Some(Preset::Robust)),
                build(algo, None),
                "{algo}"
            );
        }
    }

    #[test]
    fn sets_override_defaults_and_unknown_keys_are_named() {
        let sets = vec![
            "algo.gamma=0.95".to_string(),
            "algo.ppo.lambda=0.9".to_string(),
            "hidden=[32, 16]".to_string(),
            "env=CartPole-v1".into(),
        ];
        let c = RunConfig::build(Algorithm::Ppo, "Pendulum-v1", None, &sets).expect("valid");
        assert_eq!(
            common(&c).gamma,
            0.95,
            "algo.<key> is short for algo.ppo.<key>"
        );
        assert_eq!(common(&c).lambda, 0.9);
        assert_eq!(c.train.hidden, vec![32, 16]);
        assert_eq!(c.train.env, "CartPole-v1");

        let build = |algo, set: &str| RunConfig::build(algo, "x", None, &[set.to_string()]);
        let err = build(Algorithm::Apo, "algo.gama=0.9").unwrap_err();
        assert_eq!(
            err.to_string(),
            "unknown config key `algo.apo.gama`; did you mean `algo.apo.gamma`?"
        );
        // type errors in the user's words: what was found, written short, and the key's range
        let err = build(Algorithm::Apo, "epochs=1e3").unwrap_err().to_string();
        assert!(
            err.contains("without a point or exponent, `1000`") && err.contains("1..=1000000000"),
            "{err}"
        );
        let err = build(Algorithm::Apo, "steps_per_epoch=1e308")
            .unwrap_err()
            .to_string();
        assert!(err.contains("1e308") && err.len() < 300, "{err}");
        let err = build(Algorithm::Ppo, "algo.clip=\"x\"")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("config key `algo.ppo.clip`") && err.contains("(0, 1)"),
            "the algorithm's name stays in the key: {err}"
        );
        let err = build(Algorithm::Apo, "epochs=010").unwrap_err().to_string();
        assert!(
            err.contains("leading zeros") && err.contains("`10`"),
            "{err}"
        );
        // no suggestion from another part of the key than its last
        let err = build(Algorithm::Ppo, "algo.nosuch=1")
            .unwrap_err()
            .to_string();
        assert_eq!(err, "unknown config key `algo.ppo.nosuch`");
        let file = tempfile::NamedTempFile::new().expect("temp");
        std::fs::write(file.path(), "[algo.nosuch]\nx = 1\n[algo.ppo]\n").expect("write");
        let err = RunConfig::build(Algorithm::Ppo, "x", Some(file.path()), &[])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("`nosuch` is not an algorithm") && err.contains("vmpo"),
            "{err}"
        );
        let err = build(Algorithm::Apo, "algo.k=\"seven\"").unwrap_err();
        assert!(
            err.to_string()
                .starts_with("config key `algo.apo.k`: wrong kind of value"),
            "{err}"
        );
        let err = build(Algorithm::Apo, "algo.gamma=1.0").unwrap_err();
        assert_eq!(
            err.to_string(),
            "invalid `algo.apo.gamma` = 1: must be in [0, 1)"
        );
        // a key of other algorithms, named with its owners
        let err = build(Algorithm::Apo, "algo.clip=0.1").unwrap_err();
        assert_eq!(
            err.to_string(),
            "unknown config key `algo.apo.clip`: apo has no setting `clip` (it is a setting of papo, ppo, mvpi, cvar, retcap, tailppo)"
        );
        let err = build(Algorithm::Trpo, "algo.policy_update.minibatch_size=64").unwrap_err();
        assert!(
            err.to_string().contains(
                "(it is a setting of papo, ppo, a2c, espo, alphappo, vmpo, mvpi, cvar, retcap, tailppo)"
            ),
            "{err}"
        );
        // another algorithm's section
        let err = build(Algorithm::Apo, "algo.papo.clip=0.1").unwrap_err();
        assert!(
            err.to_string().starts_with(
                "`algo.papo` is in the section of papo, but the run's algorithm is apo"
            ),
            "{err}"
        );

        let c =
            build(Algorithm::Ppo, "algo.policy_update.minibatch_size=64").expect("optional key");
        let AlgoConfig::Ppo(ppo) = &c.train.algo else {
            panic!("ppo")
        };
        assert_eq!(ppo.policy_update.minibatch_size, Some(64));
    }

    #[test]
    fn config_files_hold_their_algorithms_section() {
        let dir = tempfile::tempdir().expect("tempdir");
        let write = |name: &str, text: &str| {
            let path = dir.path().join(name);
            std::fs::write(&path, text).expect("write");
            path
        };
        let papo = write("papo.toml", "[algo.papo]\nclip = 0.1\n");
        assert_eq!(file_algorithm(&papo).expect("reads"), Some(Algorithm::Papo));
        let c = RunConfig::build(Algorithm::Papo, "x", Some(&papo), &[]).expect("valid");
        let AlgoConfig::Papo(p) = &c.train.algo else {
            panic!("papo")
        };
        assert_eq!(p.clip, 0.1);
        let err = RunConfig::build(Algorithm::Apo, "x", Some(&papo), &[]).unwrap_err();
        assert!(
            err.to_string().contains("the run's algorithm is apo"),
            "{err}"
        );

        let none = write("none.toml", "epochs = 3\n");
        assert_eq!(file_algorithm(&none).expect("reads"), None);
        let err = RunConfig::load(&none).unwrap_err();
        assert!(
            err.to_string()
                .contains("has no algorithm section [algo.<name>]"),
            "{err}"
        );
        let two = write("two.toml", "[algo.apo]\n[algo.trpo]\n");
        let err = RunConfig::load(&two).unwrap_err();
        assert!(
            err.to_string().contains("several algorithms (apo, trpo)"),
            "{err}"
        );

        // a run directory's config.toml of the earlier flat format still loads
        let legacy = write(
            "legacy.toml",
            "env = \"Hopper-v4\"\n[algo]\nalgo = \"trpo\"\ngamma = 0.95\nk = 7.0\nclip = 0.2\n\
             [algo.trust_region]\nmax_kl = 0.01\n",
        );
        let c = RunConfig::load(&legacy).expect("the flat format is migrated");
        let AlgoConfig::Trpo(t) = &c.train.algo else {
            panic!("trpo")
        };
        assert_eq!((t.gamma, t.trust_region.max_kl), (0.95, 0.01));
    }

    #[test]
    fn shipped_configs_are_the_paper_defaults() {
        let configs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs");
        for (dir, &algo) in [configs.clone(), configs.join("guard"), configs.join("hand")]
            .iter()
            .flat_map(|dir| Algorithm::ALL.iter().map(move |a| (dir, a)))
        {
            let file = dir.join(format!("{algo}.toml"));
            assert_eq!(
                file_algorithm(&file).ok().flatten(),
                Some(algo),
                "{}",
                file.display()
            );
            let c = RunConfig::build(algo, "x", Some(&file), &[])
                .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
            assert_eq!(c, RunConfig::defaults(algo, "x"), "{}", file.display());
        }
        // the Atari configs: the defaults with 500 epochs and 1 000-step trajectories
        let atari = std::fs::read_dir(configs.join("atari")).expect("configs/atari");
        let mut algorithms = Vec::new();
        for file in atari.map(|e| e.expect("an entry").path()) {
            let algo = file_algorithm(&file)
                .ok()
                .flatten()
                .unwrap_or_else(|| panic!("{}: no algorithm section", file.display()));
            let c = RunConfig::build(algo, "x", Some(&file), &[])
                .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
            let mut paper = RunConfig::defaults(algo, "x");
            paper.train.epochs = 500;
            paper.train.max_episode_steps = 1000;
            assert_eq!(c, paper, "{}", file.display());
            algorithms.push(algo.to_string());
        }
        algorithms.sort();
        assert_eq!(algorithms, ["a2c", "apo", "papo", "ppo", "trpo"]);
        // the tuned configs: each names its algorithm and builds
        let tuned = std::fs::read_dir(configs.join("tuned")).expect("configs/tuned");
        for file in tuned.map(|e| e.expect("an entry").path()) {
            let algo = file_algorithm(&file)
                .ok()
                .flatten()
                .unwrap_or_else(|| panic!("{}: no algorithm section", file.display()));
            RunConfig::build(algo, "x", Some(&file), &[])
                .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        }
    }

    #[test]
    fn every_key_is_documented_and_the_documented_toml_parses_back() {
        for &algo in Algorithm::ALL {
            let mut c = RunConfig::defaults(algo, "Hopper");
            if let AlgoConfig::Ppo(p) = &mut c.train.algo {
                p.policy_update.minibatch_size = Some(64);
            }
            let mut keys = Vec::new();
            all_keys(&to_table(&c), "", &mut keys);
            for update in ["policy_update", "value_update"] {
                if keys.contains(&format!("algo.{algo}.{update}")) {
                    keys.extend(
                        OPTIONAL_FIELDS
                            .iter()
                            .map(|f| format!("algo.{algo}.{update}.{f}")),
                    );
                }
            }
            for key in &keys {
                assert!(
                    !key_doc(key, &c.train.algo).is_empty(),
                    "config key `{key}` has no documentation"
                );
            }
            for (key, _) in KEY_DOCS {
                assert!(
                    keys.iter().any(|k| k == key),
                    "KEY_DOCS documents `{key}`, which is not a config key"
                );
            }
            for (key, _) in c.train.algo.settings().key_docs() {
                let key = format!("algo.{algo}.{key}");
                assert!(
                    keys.contains(&key),
                    "{algo} documents `{key}`, which is not a config key"
                );
            }
            let text = c.documented_toml();
            assert!(
                text.contains(&format!("[algo.{algo}]\n"))
                    && text.contains("# discount factor γ; [0, 1)\ngamma = 0.99"),
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
        assert!(err.to_string().contains("`init_log_std` = 1e30"), "{err}");
        let action = ActionKind::Continuous { dim: 3 };
        let paper = RunConfig::defaults(Algorithm::Apo, "Hopper");
        // the paper's Hopper run: ~10 k parameters, 30 000 samples of 11 + 3 + 6 floats
        let estimate = memory_estimate(&paper, 11, action, paper.env_bytes());
        assert!(
            estimate > 30_000.0 * 128.0 * 48.0 && estimate < 1e9,
            "{estimate}"
        );
        paper
            .check_memory(11, action)
            .expect("the paper's Hopper run fits");
        let mut wide = paper;
        wide.train.hidden = vec![1 << 20, 1 << 20];
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
