//! Training: standardization, initialization, mini-batch Adam with
//! whole-batch matrix products, early stopping.

use nalgebra::{DMatrix, DVector};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::error::TrainError;
use super::hyperparams::{Activation, MlpValidParams};
use super::linalg::{Transposed, multiply, sum};
use super::split::split_rows;
use super::{Dataset, EpochReport, History, Mlp};

/// Separate ChaCha streams keep split, init and shuffling independent: a
/// change in one does not perturb the others.
const STREAM_SPLIT: u64 = 0;
const STREAM_INIT: u64 = 1;
const STREAM_SHUFFLE: u64 = 2;

const BETA1: f64 = 0.9;
const BETA2: f64 = 0.999;
const EPSILON: f64 = 1e-8;

pub(crate) fn rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    rng
}

/// One dense layer: `out = input * w + b`, `w` is fan_in x fan_out.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Layer {
    pub(crate) w: DMatrix<f64>,
    pub(crate) b: DVector<f64>,
}

impl Layer {
    fn zeros(fan_in: usize, fan_out: usize) -> Self {
        Self {
            w: DMatrix::zeros(fan_in, fan_out),
            b: DVector::zeros(fan_out),
        }
    }
}

/// Per-column mean and standard deviation.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Scaler {
    pub(crate) mean: Vec<f64>,
    pub(crate) std: Vec<f64>,
}

impl Scaler {
    fn fit(m: &DMatrix<f64>) -> Self {
        let n = m.nrows().max(1) as f64;
        let mean: Vec<f64> = m.column_iter().map(|c| c.sum() / n).collect();
        let std = m
            .column_iter()
            .zip(&mean)
            .map(|(c, mu)| {
                let sd = (c.iter().map(|v| (v - mu).powi(2)).sum::<f64>() / n).sqrt();
                // A constant column carries no information; avoid dividing by 0.
                if sd > 1e-12 { sd } else { 1.0 }
            })
            .collect();
        Self { mean, std }
    }

    pub(crate) fn standardize(&self, m: &DMatrix<f64>) -> DMatrix<f64> {
        DMatrix::from_fn(m.nrows(), m.ncols(), |r, c| {
            (m[(r, c)] - self.mean[c]) / self.std[c]
        })
    }

    pub(crate) fn restore(&self, mut m: DMatrix<f64>) -> DMatrix<f64> {
        for (c, mut col) in m.column_iter_mut().enumerate() {
            col.apply(|v| *v = *v * self.std[c] + self.mean[c]);
        }
        m
    }
}

/// Xavier (Glorot) uniform for tanh and the linear output, He uniform for
/// ReLU/GELU hidden layers; zero biases.
fn init_layers(sizes: &[usize], act: Activation, rng: &mut ChaCha8Rng) -> Vec<Layer> {
    let last = sizes.len() - 2;
    sizes
        .windows(2)
        .enumerate()
        .map(|(l, w)| {
            let (fan_in, fan_out) = (w[0] as f64, w[1] as f64);
            let limit = match act {
                Activation::Relu | Activation::Gelu if l < last => (6.0 / fan_in).sqrt(),
                _ => (6.0 / (fan_in + fan_out)).sqrt(),
            };
            let mut layer = Layer::zeros(w[0], w[1]);
            layer.w.apply(|v| *v = rng.random_range(-limit..limit));
            layer
        })
        .collect()
}

fn add_bias(z: &mut DMatrix<f64>, b: &DVector<f64>) {
    for (mut col, bias) in z.column_iter_mut().zip(b.iter()) {
        col.add_scalar_mut(*bias);
    }
}

/// Inference on standardized inputs (allocates per layer; not the hot loop).
pub(crate) fn forward(layers: &[Layer], act: Activation, x: &DMatrix<f64>) -> DMatrix<f64> {
    let mut h = x.clone();
    for (l, layer) in layers.iter().enumerate() {
        let mut z = DMatrix::zeros(h.nrows(), layer.w.ncols());
        z.gemm(1.0, &h, &layer.w, 0.0);
        add_bias(&mut z, &layer.b);
        if l + 1 < layers.len() {
            z.apply(|v| *v = act.eval(*v));
        }
        h = z;
    }
    h
}

fn mse(pred: &DMatrix<f64>, target: &DMatrix<f64>) -> f64 {
    let n = (pred.len().max(1)) as f64;
    pred.iter()
        .zip(target.iter())
        .map(|(p, t)| (p - t).powi(2))
        .sum::<f64>()
        / n
}

/// Buffers for one batch size, allocated once and reused every step.
struct Workspace {
    x: DMatrix<f64>,
    y: DMatrix<f64>,
    /// Pre-activations per layer (the last one is the network output).
    z: Vec<DMatrix<f64>>,
    /// Hidden activations per hidden layer.
    a: Vec<DMatrix<f64>>,
    /// dLoss/dz per layer.
    delta: Vec<DMatrix<f64>>,
}

impl Workspace {
    fn new(rows: usize, sizes: &[usize]) -> Self {
        let per_layer = |k: usize| -> Vec<DMatrix<f64>> {
            sizes[1..1 + k]
                .iter()
                .map(|&s| DMatrix::zeros(rows, s))
                .collect()
        };
        let layers = sizes.len() - 1;
        Self {
            x: DMatrix::zeros(rows, sizes[0]),
            y: DMatrix::zeros(rows, sizes[layers]),
            z: per_layer(layers),
            a: per_layer(layers - 1),
            delta: per_layer(layers),
        }
    }

    fn gather(&mut self, x: &DMatrix<f64>, y: &DMatrix<f64>, rows: &[usize]) {
        copy_rows(&mut self.x, x, rows);
        copy_rows(&mut self.y, y, rows);
    }
}

fn copy_rows(dst: &mut DMatrix<f64>, src: &DMatrix<f64>, rows: &[usize]) {
    for (mut d, s) in dst.column_iter_mut().zip(src.column_iter()) {
        for (slot, &i) in d.iter_mut().zip(rows) {
            *slot = s[i];
        }
    }
}

/// Network plus gradient and Adam moment buffers of the same shapes.
struct Trainer<'p> {
    params: &'p MlpValidParams,
    layers: Vec<Layer>,
    grads: Vec<Layer>,
    m: Vec<Layer>,
    v: Vec<Layer>,
    step: u64,
}

impl<'p> Trainer<'p> {
    fn new(params: &'p MlpValidParams, layers: Vec<Layer>) -> Self {
        let zeros: Vec<Layer> = layers
            .iter()
            .map(|l| Layer::zeros(l.w.nrows(), l.w.ncols()))
            .collect();
        Self {
            params,
            layers,
            grads: zeros.clone(),
            m: zeros.clone(),
            v: zeros,
            step: 0,
        }
    }

    /// Forward, backward and Adam update on the batch in `ws`; returns the
    /// batch MSE before the update.
    fn step(&mut self, ws: &mut Workspace) -> f64 {
        self.forward(ws);
        let loss = self.output_delta(ws);
        self.backward(ws);
        self.adam_update();
        loss
    }

    fn forward(&self, ws: &mut Workspace) {
        let act = self.params.activation;
        let last = self.layers.len() - 1;
        for (l, layer) in self.layers.iter().enumerate() {
            let input = if l == 0 { &ws.x } else { &ws.a[l - 1] };
            ws.z[l].gemm(1.0, input, &layer.w, 0.0);
            add_bias(&mut ws.z[l], &layer.b);
            if l < last {
                match act {
                    // One tight loop over the slices, vectorized.
                    Activation::Tanh => {
                        super::tanh::tanh_slice(ws.a[l].as_mut_slice(), ws.z[l].as_slice())
                    }
                    _ => ws.a[l].zip_apply(&ws.z[l], |a, z| *a = act.eval(z)),
                }
            }
        }
    }

    /// dLoss/dOutput for the mean squared error; returns the loss.
    fn output_delta(&self, ws: &mut Workspace) -> f64 {
        let last = self.layers.len() - 1;
        let count = ws.y.len() as f64;
        let mut sse = 0.0;
        ws.delta[last].zip_zip_apply(&ws.z[last], &ws.y, |d, out, target| {
            let e = out - target;
            sse += e * e;
            *d = 2.0 * e / count;
        });
        sse / count
    }

    fn backward(&mut self, ws: &mut Workspace) {
        let act = self.params.activation;
        for l in (0..self.layers.len()).rev() {
            let input = if l == 0 { &ws.x } else { &ws.a[l - 1] };
            let grad = &mut self.grads[l];
            multiply(
                &mut grad.w,
                (input, Transposed::Yes),
                (&ws.delta[l], Transposed::No),
            );
            for (g, col) in grad.b.iter_mut().zip(ws.delta[l].column_iter()) {
                *g = sum(col.as_slice());
            }
            if l == 0 {
                break;
            }
            let (below, rest) = ws.delta.split_at_mut(l);
            let w = &self.layers[l].w;
            multiply(
                &mut below[l - 1],
                (&rest[0], Transposed::No),
                (w, Transposed::Yes),
            );
            match act {
                Activation::Tanh => {
                    for (d, a) in below[l - 1].iter_mut().zip(ws.a[l - 1].iter()) {
                        *d *= 1.0 - a * a;
                    }
                }
                _ => below[l - 1].zip_zip_apply(&ws.z[l - 1], &ws.a[l - 1], |d, z, a| {
                    *d *= act.derivative(z, a)
                }),
            }
        }
    }

    /// Adam with bias correction; weight decay is decoupled (AdamW) and
    /// skips biases.
    fn adam_update(&mut self) {
        self.step += 1;
        let t = self.step as f64;
        let lr = self.params.learning_rate;
        let lr_t = lr * (1.0 - BETA2.powf(t)).sqrt() / (1.0 - BETA1.powf(t));
        let decay = lr * self.params.weight_decay;
        for l in 0..self.layers.len() {
            let (p, g) = (&mut self.layers[l], &self.grads[l]);
            let (m, v) = (&mut self.m[l], &mut self.v[l]);
            adam(
                p.w.as_mut_slice(),
                g.w.as_slice(),
                m.w.as_mut_slice(),
                v.w.as_mut_slice(),
                lr_t,
                decay,
            );
            adam(
                p.b.as_mut_slice(),
                g.b.as_slice(),
                m.b.as_mut_slice(),
                v.b.as_mut_slice(),
                lr_t,
                0.0,
            );
        }
    }
}

fn adam(p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64], lr_t: f64, decay: f64) {
    for (((p, g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
        *m = BETA1 * *m + (1.0 - BETA1) * g;
        *v = BETA2 * *v + (1.0 - BETA2) * g * g;
        *p -= lr_t * *m / (v.sqrt() + EPSILON) + decay * *p;
    }
}

/// Standardized train/validation matrices and the scalers that made them.
struct Prepared {
    x: DMatrix<f64>,
    y: DMatrix<f64>,
    valid: Option<(DMatrix<f64>, DMatrix<f64>)>,
    input: Scaler,
    output: Scaler,
}

fn prepare(
    params: &MlpValidParams,
    data: &Dataset,
    validation: Option<&Dataset>,
) -> Result<Prepared, TrainError> {
    data.validate("training")?;
    let (train, valid) = match validation {
        Some(v) => {
            v.validate("validation")?;
            data.check_same_width(v)?;
            (data.clone(), Some(v.clone()))
        }
        None => {
            let mut rng = rng(params.seed, STREAM_SPLIT);
            let (t, v) = split_rows(data, params.validation_fraction, &mut rng)?;
            let valid = (!v.is_empty()).then(|| data.select_rows(&v));
            (data.select_rows(&t), valid)
        }
    };
    let input = Scaler::fit(&train.inputs);
    let output = Scaler::fit(&train.targets);
    let valid = valid.map(|v| (input.standardize(&v.inputs), output.standardize(&v.targets)));
    Ok(Prepared {
        x: input.standardize(&train.inputs),
        y: output.standardize(&train.targets),
        valid,
        input,
        output,
    })
}

/// Shuffled mini-batches over the training rows, with reused workspaces.
struct Batches {
    batch: usize,
    full: Workspace,
    /// Workspace for the smaller last batch, if the rows do not divide evenly.
    tail: Option<Workspace>,
    order: Vec<usize>,
    rng: ChaCha8Rng,
}

impl Batches {
    fn new(n: usize, batch_size: usize, sizes: &[usize], seed: u64) -> Self {
        let batch = batch_size.min(n);
        Self {
            batch,
            full: Workspace::new(batch, sizes),
            tail: (!n.is_multiple_of(batch)).then(|| Workspace::new(n % batch, sizes)),
            order: (0..n).collect(),
            rng: rng(seed, STREAM_SHUFFLE),
        }
    }

    /// One pass over the shuffled rows; returns the mean training loss.
    fn run_epoch(&mut self, trainer: &mut Trainer<'_>, prep: &Prepared) -> f64 {
        self.order.shuffle(&mut self.rng);
        let mut total = 0.0;
        for rows in self.order.chunks(self.batch) {
            let ws = match self.tail.as_mut() {
                Some(t) if rows.len() < self.batch => t,
                _ => &mut self.full,
            };
            ws.gather(&prep.x, &prep.y, rows);
            total += trainer.step(ws) * rows.len() as f64;
        }
        total / self.order.len() as f64
    }
}

/// Tracks the best validation loss and when to stop.
struct EarlyStop {
    best_loss: f64,
    best_epoch: usize,
    best_layers: Option<Vec<Layer>>,
}

impl EarlyStop {
    /// Records an epoch; returns true when it improved on the best. Without
    /// validation every epoch counts as best, so the final weights are kept.
    fn observe(&mut self, epoch: usize, valid_loss: Option<f64>, layers: &[Layer]) -> bool {
        let Some(loss) = valid_loss else {
            self.best_epoch = epoch;
            return true;
        };
        if loss < self.best_loss {
            self.best_loss = loss;
            self.best_epoch = epoch;
            self.best_layers = Some(layers.to_vec());
            return true;
        }
        false
    }
}

impl MlpValidParams {
    /// Trains on `data`, holding out `validation_fraction` of it (by whole
    /// groups when `data.groups` is set) for early stopping.
    pub fn fit(&self, data: &Dataset) -> Result<Mlp, TrainError> {
        self.fit_with(data, None, &mut |_| {})
    }

    /// Trains on `data`; validates on `validation` when given (no split),
    /// else on a held-out share of `data`. Calls `progress` after each epoch.
    /// Losses are MSEs of standardized targets, so every joint weighs alike.
    pub fn fit_with(
        &self,
        data: &Dataset,
        validation: Option<&Dataset>,
        progress: &mut dyn FnMut(EpochReport),
    ) -> Result<Mlp, TrainError> {
        let prep = prepare(self, data, validation)?;
        let sizes: Vec<usize> = std::iter::once(prep.x.ncols())
            .chain(self.hidden.iter().copied())
            .chain(std::iter::once(prep.y.ncols()))
            .collect();
        let layers = init_layers(&sizes, self.activation, &mut rng(self.seed, STREAM_INIT));
        let mut trainer = Trainer::new(self, layers);
        let history = self.train_epochs(&mut trainer, &prep, &sizes, progress)?;
        Ok(Mlp {
            layers: trainer.layers,
            activation: self.activation,
            input: prep.input,
            output: prep.output,
            seed: self.seed,
            history,
        })
    }

    fn train_epochs(
        &self,
        trainer: &mut Trainer<'_>,
        prep: &Prepared,
        sizes: &[usize],
        progress: &mut dyn FnMut(EpochReport),
    ) -> Result<History, TrainError> {
        let mut batches = Batches::new(prep.x.nrows(), self.batch_size, sizes, self.seed);
        let mut history = History::default();
        let mut stop = EarlyStop {
            best_loss: f64::INFINITY,
            best_epoch: 0,
            best_layers: None,
        };
        for epoch in 1..=self.max_epochs {
            let train_loss = batches.run_epoch(trainer, prep);
            let valid_loss = prep
                .valid
                .as_ref()
                .map(|(x, y)| mse(&forward(&trainer.layers, self.activation, x), y));
            if !train_loss.is_finite() || valid_loss.is_some_and(|v| !v.is_finite()) {
                return Err(TrainError::NonFiniteLoss { epoch });
            }
            history.train_loss.push(train_loss);
            history.valid_loss.extend(valid_loss);
            let improved = stop.observe(epoch, valid_loss, &trainer.layers);
            let stopping = self
                .patience
                .is_some_and(|p| valid_loss.is_some() && epoch - stop.best_epoch >= p);
            progress(EpochReport {
                epoch,
                max_epochs: self.max_epochs,
                train_loss,
                valid_loss,
                best_epoch: stop.best_epoch,
                improved,
                stopping,
            });
            if stopping {
                break;
            }
        }
        if let Some(best) = stop.best_layers {
            trainer.layers = best;
        }
        history.best_epoch = stop.best_epoch;
        Ok(history)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Compares analytic gradients with central finite differences.
    #[test]
    fn gradients_match_finite_differences() {
        for act in [Activation::Tanh, Activation::Relu, Activation::Gelu] {
            let params = Mlp::params()
                .hidden(vec![5, 4])
                .activation(act)
                .check()
                .unwrap();
            let sizes = [3, 5, 4, 2];
            let layers = init_layers(&sizes, act, &mut rng(7, STREAM_INIT));
            let mut trainer = Trainer::new(&params, layers);
            let mut ws = Workspace::new(6, &sizes);
            ws.x = DMatrix::from_fn(6, 3, |r, c| ((r * 3 + c) as f64 * 0.37).sin());
            ws.y = DMatrix::from_fn(6, 2, |r, c| ((r + c) as f64 * 0.5).cos());
            trainer.forward(&mut ws);
            trainer.output_delta(&mut ws);
            trainer.backward(&mut ws);
            let loss_at = |t: &mut Trainer, ws: &mut Workspace| {
                t.forward(ws);
                t.output_delta(ws)
            };
            for l in 0..3 {
                for idx in [0, 3] {
                    let orig = trainer.layers[l].w.as_slice()[idx];
                    let h = 1e-6;
                    trainer.layers[l].w.as_mut_slice()[idx] = orig + h;
                    let up = loss_at(&mut trainer, &mut ws);
                    trainer.layers[l].w.as_mut_slice()[idx] = orig - h;
                    let down = loss_at(&mut trainer, &mut ws);
                    trainer.layers[l].w.as_mut_slice()[idx] = orig;
                    let numeric = (up - down) / (2.0 * h);
                    let analytic = trainer.grads[l].w.as_slice()[idx];
                    assert!(
                        (numeric - analytic).abs() < 1e-6,
                        "{act:?} layer {l}: {numeric} vs {analytic}"
                    );
                }
            }
        }
    }
}
