//! Strict loading, like PyTorch's `load_state_dict(strict=True)`: a network
//! takes each parameter by name and shape while it is built; at the end,
//! one error lists every missing, unexpected and mis-shaped tensor.

use super::{TensorMap, esc};
use crate::error::{NetError, Result, shape_str};
use crate::tensor::Tensor;

pub struct WeightLoader {
    net: String,
    map: TensorMap,
    missing: Vec<String>,
    misshaped: Vec<String>,
    not_float: Vec<String>,
}

impl WeightLoader {
    /// `net` names the network in error messages ("MST-S").
    pub fn new(net: impl Into<String>, map: TensorMap) -> Self {
        Self {
            net: net.into(),
            map,
            missing: Vec::new(),
            misshaped: Vec::new(),
            not_float: Vec::new(),
        }
    }

    /// Takes the float tensor `name` of shape `shape`. On a problem it is
    /// recorded for [`finish`](Self::finish) and zeros stand in, so building
    /// goes on and every problem is reported at once.
    pub fn take(&mut self, name: &str, shape: &[usize]) -> Tensor {
        match self.map.remove(name) {
            None => self
                .missing
                .push(format!("  missing: {name} {}", shape_str(shape))),
            // Name, shape and type come from the header: a tensor the
            // network does not want as it is is never decoded.
            Some(t) if t.shape != shape => self.misshaped.push(format!(
                "  wrong shape: {name}: got {}, wanted {}",
                shape_str(&t.shape),
                shape_str(shape)
            )),
            Some(t) if !t.dtype.is_float() => self
                .not_float
                .push(format!("  not floating point: {name} ({:?})", t.dtype)),
            Some(t) => return t.into_stored().tensor,
        }
        Tensor::zeros(shape.to_vec())
    }

    /// Accepts the bookkeeping buffer `name` (BatchNorm's
    /// `num_batches_tracked`, an integer scalar that inference ignores)
    /// when present; its absence is not an error (older PyTorch omits it).
    pub fn skip_buffer(&mut self, name: &str) {
        if let Some(t) = self.map.remove(name)
            && t.numel() != 1
        {
            self.misshaped.push(format!(
                "  wrong shape: {name}: got {} {:?}, wanted an integer scalar",
                shape_str(&t.shape),
                t.dtype
            ));
        }
    }

    /// Succeeds only if every taken tensor was present with the right shape
    /// and no tensor of the checkpoint was left unused.
    pub fn finish(self) -> Result<()> {
        let unexpected: Vec<String> = self
            .map
            .headers()
            .map(|(n, t)| format!("  unexpected: {} {}", esc(n), shape_str(&t.shape)))
            .collect();
        let mut report = Vec::new();
        for (title, list) in [
            ("missing", &self.missing),
            ("unexpected", &unexpected),
            ("mis-shaped", &self.misshaped),
            ("non-float", &self.not_float),
        ] {
            if !list.is_empty() {
                report.push(format!("{} {title}:", list.len()));
                report.extend(list.iter().cloned());
            }
        }
        if report.is_empty() {
            return Ok(());
        }
        Err(NetError::WeightMismatch {
            path: self.map.path().to_path_buf(),
            net: self.net,
            report: report.join("\n"),
        })
    }
}
