//! The critic's regression on the host ([`Kernels::Host`](crate::kernels::Kernels::Host)):
//! the same loss, Adam and minibatches as [`crate::proximal::value_update`], with the
//! network's passes on [`HostNet`] and Adam in one loop over the parameters.
//!
//! Both paths draw the same minibatches from the same random stream, and the value network
//! and its Adam state stay Burn's (a module and an optimizer record, read before and written
//! back after the fit), so checkpoints do not depend on the path and a run may change it on
//! resume. Only the rounding differs (tests compare the two).

use burn::backend::Autodiff;
use burn::optim::adaptor::OptimizerAdaptor;
use burn::optim::Adam;
use burn::tensor::backend::Backend;
use rand::Rng;

use crate::adam::HostAdam;
use crate::buffer::Batch;
use crate::collective::Comm;
use crate::host_net::HostNet;
use crate::proximal::{minibatches, ProximalConfig, ValueReport};
use crate::value::ValueNet;

type Ad<B> = Autodiff<B>;
type ValueAdam<B> = OptimizerAdaptor<Adam, ValueNet<Ad<B>>, Ad<B>>;

/// A [`HostNet`] with one output trained by Adam on the mean squared error.
#[derive(Debug, Clone)]
pub(crate) struct HostRegression {
    net: HostNet,
    /// Adam's state, `[num_params]`.
    adam: HostAdam,
    /// A minibatch's gathered rows, `[n, input]` and `[n]`.
    gathered: (Vec<f32>, Vec<f32>),
    /// The ranks whose rows, together, are the regression's data.
    comm: Comm,
}

impl HostRegression {
    /// From per-layer `(weight [input, output] row-major, bias [output])` and the Adam state
    /// in the same flat order (`None`: no step taken yet). `None` if the shapes do not chain,
    /// the last layer has more than one output or the state is of another size.
    pub(crate) fn new(layers: &[(Vec<f32>, Vec<f32>)], adam: Option<HostAdam>) -> Option<Self> {
        let net = HostNet::new(layers).filter(|net| net.output() == 1)?;
        let n = net.num_params();
        let adam = adam.unwrap_or_else(|| HostAdam::new(n));
        (adam.len() == n && adam.moment_2.len() == n).then_some(Self {
            net,
            adam,
            gathered: (Vec::new(), Vec::new()),
            comm: Comm::default(),
        })
    }

    /// The regression over the union of the rows of `comm`'s ranks (each passes its own):
    /// losses are global means and gradients are summed before each Adam step.
    pub(crate) fn with_comm(mut self, comm: Comm) -> Self {
        self.comm = comm;
        self
    }

    /// `Σ` over this rank's parts of the squared errors, and the global mean of it over `n`
    /// rows on this rank → the global mean.
    fn global_mean(&self, local: f64, rows: usize) -> f64 {
        let mut totals = [local, rows as f64];
        self.comm.sum(&mut totals);
        totals[0] / totals[1].max(1.0)
    }

    /// Mean squared error of the predictions on `x: [n, input]` against `y: [n]`.
    pub(crate) fn loss(&mut self, x: &[f32], y: &[f32]) -> f64 {
        self.net.run(x, |w, part, rows, x_rows| {
            w.forward(part, x_rows);
            part.sum = squared_error(part.output_and_head().0, &y[rows]);
        });
        let local = self.net.parts().iter().map(|p| p.sum).sum::<f64>();
        self.global_mean(local, y.len())
    }

    /// One Adam step with learning rate `lr` on the mean squared error of `x: [n, input]`
    /// against `y: [n]`; returns the loss before the step. With several ranks, of the mean
    /// over every rank's rows.
    pub(crate) fn step(&mut self, x: &[f32], y: &[f32], lr: f32) -> f64 {
        let rows = self.comm.total(y.len());
        let scale = 2.0 / rows.max(1) as f32;
        self.net.run(x, |w, part, rows, x_rows| {
            w.forward(part, x_rows);
            let y = &y[rows];
            let (out, delta) = part.output_and_head();
            let sum = squared_error(out, y);
            delta.clear();
            delta.extend(out.iter().zip(y).map(|(v, t)| scale * (v - t)));
            part.sum = sum;
            w.backward(part, x_rows);
        });
        self.net.sum_grads();
        let mut loss = self.net.parts().iter().map(|p| p.sum).sum::<f64>();
        if self.comm.is_distributed() {
            // the ranks' gradients and squared errors, summed in one reduction
            let mut totals: Vec<f64> = self.net.grads.iter().map(|&g| f64::from(g)).collect();
            totals.push(loss);
            self.comm.sum(&mut totals);
            loss = totals.pop().unwrap_or(0.0);
            for (g, t) in self.net.grads.iter_mut().zip(&totals) {
                *g = *t as f32;
            }
        }
        let loss = loss / rows.max(1) as f64;
        self.adam
            .step(self.net.params.iter_mut(), &self.net.grads, lr);
        loss
    }

    /// [`HostRegression::step`] on the rows `rows` of `x: [N, input]`, `y: [N]`.
    pub(crate) fn step_rows(&mut self, x: &[f32], y: &[f32], rows: &[usize], lr: f32) -> f64 {
        let width = self.net.input();
        let (mut gx, mut gy) = std::mem::take(&mut self.gathered);
        gx.clear();
        gy.clear();
        for &r in rows {
            gx.extend_from_slice(&x[r * width..(r + 1) * width]);
            gy.push(y[r]);
        }
        let loss = self.step(&gx, &gy, lr);
        self.gathered = (gx, gy);
        loss
    }
}

/// `Σ (out − y)²` in f64.
fn squared_error(out: &[f32], y: &[f32]) -> f64 {
    out.iter()
        .zip(y)
        .map(|(v, t)| {
            let e = f64::from(v - t);
            e * e
        })
        .sum()
}

/// [`crate::proximal::value_update`] on the host: `config.iters` passes of Adam descending
/// `mean((V(s) − ret)²)` over `batch` (`obs: [n, observation_dim]`, `ret: [n]`), minibatches
/// drawn from `rng` exactly as the Burn path draws them. Returns the updated network and
/// optimizer, or `None` (nothing consumed from `rng`) when the network is not the
/// built-in MLP shape the kernel handles.
pub(crate) fn host_value_update<B: Backend>(
    value: &ValueNet<Ad<B>>,
    optim: &ValueAdam<B>,
    batch: &Batch,
    config: &ProximalConfig,
    comm: &Comm,
    rng: &mut impl Rng,
) -> Option<(ValueNet<Ad<B>>, ValueAdam<B>, ValueReport)> {
    let adam = HostAdam::read(value, optim);
    let mut fit =
        HostRegression::new(&value.net.host_layers(), Some(adam))?.with_comm(comm.clone());
    if fit.net.input() * batch.len != batch.obs.len() || batch.ret.len() != batch.len {
        return None;
    }
    let (x, y) = (&batch.obs, &batch.ret);
    let lr = config.lr as f32;
    let loss_before = fit.loss(x, y);
    let mut loss_after = loss_before;
    for _ in 0..config.iters {
        match minibatches(batch.len, config.minibatch_size, rng) {
            None => loss_after = fit.step(x, y, lr),
            Some(rows) => {
                for part in rows.chunks(config.minibatch_size.unwrap_or(1)) {
                    loss_after = fit.step_rows(x, y, part, lr);
                }
            }
        }
    }
    let (value, optim) = fit
        .adam
        .write(value.clone(), optim.clone(), &fit.net.params);
    Some((
        value,
        optim,
        ValueReport {
            loss_before,
            loss_after,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Per layer, `(weight, bias)`.
    type Layers = Vec<(Vec<f32>, Vec<f32>)>;

    fn problem(seed: u64) -> (Layers, Vec<f32>, Vec<f32>) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut draw =
            |len: usize| -> Vec<f32> { (0..len).map(|_| rng.random_range(-0.8..0.8)).collect() };
        let layers = vec![
            (draw(4 * 8), draw(8)),
            (draw(8 * 8), draw(8)),
            (draw(8), draw(1)),
        ];
        let x = draw(40 * 4);
        let y = x.chunks(4).map(|r| 2.0 * r[0] - r[2] * r[3]).collect();
        (layers, x, y)
    }

    #[test]
    fn adam_descends_and_minibatch_rows_equal_a_gathered_batch() {
        let (layers, x, y) = problem(3);
        let mut reg = HostRegression::new(&layers, None).expect("shapes chain");
        let first = reg.loss(&x, &y);
        for _ in 0..300 {
            reg.step(&x, &y, 1e-2);
        }
        let last = reg.loss(&x, &y);
        assert!(last < 0.2 * first, "{first} → {last}");
        assert_eq!(reg.adam.time, 300);

        let rows = [3usize, 17, 0, 39, 8];
        let mut a = HostRegression::new(&layers, None).expect("shapes chain");
        let mut b = a.clone();
        a.step_rows(&x, &y, &rows, 1e-2);
        let gx: Vec<f32> = rows
            .iter()
            .flat_map(|&r| x[r * 4..r * 4 + 4].to_vec())
            .collect();
        let gy: Vec<f32> = rows.iter().map(|&r| y[r]).collect();
        b.step(&gx, &gy, 1e-2);
        assert_eq!(a.net.params, b.net.params);
    }

    #[test]
    fn refuses_several_outputs_and_mismatched_moments() {
        let (mut layers, _, _) = problem(1);
        assert!(HostRegression::new(&layers, Some(HostAdam::new(3))).is_none());
        layers[2] = (vec![0.0; 16], vec![0.0; 2]);
        assert!(HostRegression::new(&layers, None).is_none());
    }
}
