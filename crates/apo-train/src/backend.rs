//! The compute backend of a run's updates: [`BackendKind`] names it in a config, and
//! [`BackendKind::dispatch`] is the one place where that name becomes a Burn backend type.

use std::fmt;

use burn::tensor::backend::Backend;
use serde::{Deserialize, Serialize};

/// The compute backend of the updates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
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

/// Where the Fisher-vector products, the proximal policy steps and the value fit run
/// (`kernels`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
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

/// Code generic over the Burn backend, to run on the backend a [`BackendKind`] names
/// ([`BackendKind::dispatch`]).
pub trait OnBackend {
    /// What the code returns.
    type Output;
    /// Runs the code on backend `B`.
    fn run<B: Backend>(self) -> Self::Output;
}

impl BackendKind {
    /// Runs `code` on this backend: `NdArray`, or `Wgpu` when apo-train is built with its
    /// `wgpu` feature (the `apo` binary is).
    ///
    /// # Errors
    /// `Wgpu` in a build without the feature.
    pub fn dispatch<C: OnBackend>(self, code: C) -> anyhow::Result<C::Output> {
        match self {
            BackendKind::Cpu => Ok(code.run::<burn::backend::NdArray>()),
            #[cfg(feature = "wgpu")]
            BackendKind::Wgpu => {
                quiet_wgpu();
                Ok(code.run::<burn::backend::Wgpu>())
            }
            #[cfg(not(feature = "wgpu"))]
            BackendKind::Wgpu => anyhow::bail!(
                "backend = \"wgpu\": this build has no wgpu backend (build apo-train with its `wgpu` feature)"
            ),
        }
    }
}

/// Silences the Wayland client's "XDG_RUNTIME_DIR is invalid or not set" line, which
/// `libwayland-client` prints when the Vulkan driver probes for a display and the variable is
/// unset: apo never draws to a window, so it points the probe at a private, empty directory
/// of its own (`<tmp>/apo-runtime-<uid>`, mode 0700, reused by later runs).
#[cfg(feature = "wgpu")]
fn quiet_wgpu() {
    #[cfg(unix)]
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
        let Ok(uid) = std::fs::metadata("/proc/self").map(|m| m.uid()) else {
            return;
        };
        let dir = std::env::temp_dir().join(format!("apo-runtime-{uid}"));
        let _ = std::fs::DirBuilder::new().mode(0o700).create(&dir);
        let private = std::fs::symlink_metadata(&dir)
            .is_ok_and(|m| m.is_dir() && m.uid() == uid && m.permissions().mode() & 0o077 == 0);
        if private {
            // the variable is read by the Vulkan loader's display probe, which runs after this
            std::env::set_var("XDG_RUNTIME_DIR", &dir);
        }
    }
}
