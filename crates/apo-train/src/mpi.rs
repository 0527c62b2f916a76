//! Data-parallel training over MPI (cargo feature `mpi`), through the `mpi` crate (rsmpi) on
//! the system's Open MPI.
//!
//! [`Mpi::init`] joins the job when the process was started by `mpirun` (Open MPI sets
//! `OMPI_COMM_WORLD_SIZE`; PMI/PMIx launchers set `PMI_SIZE` or `PMIX_RANK`) and otherwise runs
//! alone without initializing MPI, so a binary built with the feature behaves like one built
//! without it. [`MpiCollective`] implements [`Collective`]: sums are reduced onto rank 0 and
//! broadcast (every rank gets bitwise the same result), maxima are all-reduced, gathers are
//! all-gathers of variable length. It counts the bytes it sends and the time it waits, for the
//! run's log.

use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

use anyhow::{bail, Context};
use apo_core::{Collective, Comm};
use mpi::collective::SystemOperation;
use mpi::datatype::PartitionMut;
use mpi::environment::Universe;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::{Count, Threading};

/// Whether this process was started by an MPI launcher.
pub fn launched() -> bool {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"]
        .iter()
        .any(|v| std::env::var_os(v).is_some())
}

/// This process's place in the job: MPI's universe (finalized when dropped) and the
/// communicator of the update, or one process alone.
pub struct Mpi {
    /// Kept alive for the whole run: dropping it finalizes MPI.
    _universe: Option<Universe>,
    collective: Option<Arc<MpiCollective>>,
}

impl Mpi {
    /// Joins the MPI job when launched by `mpirun`, else runs alone.
    ///
    /// # Errors
    /// When MPI cannot be initialized, or cannot give calls from any thread one at a time
    /// (`MPI_THREAD_SERIALIZED`).
    pub fn init() -> anyhow::Result<Self> {
        if !launched() {
            return Ok(Self {
                _universe: None,
                collective: None,
            });
        }
        let (universe, threading) = mpi::initialize_with_threading(Threading::Serialized)
            .context("MPI could not be initialized (was it already?)")?;
        if threading < Threading::Serialized {
            bail!(
                "this MPI library gives {threading:?} threading; apo needs Serialized or Multiple"
            );
        }
        let world = universe.world();
        let collective = MpiCollective {
            rank: usize::try_from(world.rank()).unwrap_or(0),
            size: usize::try_from(world.size()).unwrap_or(1),
            world: Mutex::new(World(world)),
            traffic: Mutex::new(Traffic::default()),
        };
        Ok(Self {
            _universe: Some(universe),
            collective: Some(Arc::new(collective)),
        })
    }

    /// The communicator of the update ([`apo_core::Solo`] when running alone).
    pub fn comm(&self) -> Comm {
        match &self.collective {
            Some(c) => Comm::new(Arc::clone(c) as Arc<dyn Collective>),
            None => Comm::default(),
        }
    }

    /// What the reductions have sent and waited so far.
    pub fn traffic(&self) -> Traffic {
        self.collective
            .as_ref()
            .map(|c| *c.traffic.lock().unwrap_or_else(PoisonError::into_inner))
            .unwrap_or_default()
    }

    /// Ends every process of the job with `code` (after an error on this one, so that the
    /// others do not wait for it forever). Returns only when running alone.
    pub fn abort(&self, code: i32) {
        if let Some(c) = &self.collective {
            if c.size > 1 {
                let world = c.world.lock().unwrap_or_else(PoisonError::into_inner);
                world.0.abort(code);
            }
        }
    }
}

/// The reductions' counters on one rank.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Traffic {
    /// Collective calls.
    pub calls: u64,
    /// Bytes this rank contributed (8 per `f64`).
    pub bytes: u64,
    /// Seconds spent inside the calls (transfer and waiting for the other ranks).
    pub seconds: f64,
}

/// The world communicator.
struct World(SimpleCommunicator);

// SAFETY: MPI is initialized with MPI_THREAD_SERIALIZED, which allows calls from any thread
// as long as no two run at once; every call goes through the `Mutex` holding this value.
unsafe impl Send for World {}

/// [`Collective`] over MPI's world communicator.
pub struct MpiCollective {
    rank: usize,
    size: usize,
    world: Mutex<World>,
    traffic: Mutex<Traffic>,
}

impl MpiCollective {
    /// Runs `f` on the communicator, counting `len` values and the time.
    fn call<T>(&self, len: usize, f: impl FnOnce(&SimpleCommunicator) -> T) -> T {
        let world = self.world.lock().unwrap_or_else(PoisonError::into_inner);
        let start = Instant::now();
        let out = f(&world.0);
        let mut t = self.traffic.lock().unwrap_or_else(PoisonError::into_inner);
        t.calls += 1;
        t.bytes += 8 * len as u64;
        t.seconds += start.elapsed().as_secs_f64();
        out
    }
}

impl Collective for MpiCollective {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn sum(&self, values: &mut [f64]) {
        self.call(values.len(), |world| {
            // reduce onto rank 0, then broadcast: every rank holds rank 0's bits
            let root = world.process_at_rank(0);
            let send = values.to_vec();
            if self.rank == 0 {
                root.reduce_into_root(&send[..], values, SystemOperation::sum());
            } else {
                root.reduce_into(&send[..], SystemOperation::sum());
            }
            root.broadcast_into(values);
        });
    }

    fn max(&self, values: &mut [f64]) {
        self.call(values.len(), |world| {
            let send = values.to_vec();
            world.all_reduce_into(&send[..], values, SystemOperation::max());
        });
    }

    fn gather(&self, values: &[f64]) -> Vec<Vec<f64>> {
        self.call(values.len(), |world| {
            let mine = Count::try_from(values.len()).unwrap_or(Count::MAX);
            let mut counts: Vec<Count> = vec![0; self.size];
            world.all_gather_into(&mine, &mut counts[..]);
            let displs: Vec<Count> = counts
                .iter()
                .scan(0, |acc, &c| {
                    let d = *acc;
                    *acc += c;
                    Some(d)
                })
                .collect();
            let total = counts.iter().map(|&c| c.max(0) as usize).sum();
            let mut all = vec![0.0f64; total];
            {
                let mut partition = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
                world.all_gather_varcount_into(values, &mut partition);
            }
            let mut out = Vec::with_capacity(self.size);
            let mut offset = 0;
            for &c in &counts {
                let c = c.max(0) as usize;
                out.push(all[offset..offset + c].to_vec());
                offset += c;
            }
            out
        })
    }
}
