//! The configuration of a multilayer perceptron.

use serde::{Deserialize, Serialize};

use crate::activation::Activation;
use crate::error::{Error, Result};

/// How a layer's weights are drawn. Biases always start at zero.
///
/// Serialised as `"glorot_uniform"` or `{"orthogonal": {"gain": 1.0}}`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Init {
    /// Uniform on `[-l, l]` with `l = sqrt(6 / (fan_in + fan_out))`: the
    /// default of TensorFlow's dense layers, which the RED release uses.
    GlorotUniform,
    /// A random (semi-)orthogonal matrix scaled by `gain`: for a weight
    /// matrix of shape `(in, out)`, `W^T W = gain^2 I` when `in >= out`,
    /// otherwise `W W^T = gain^2 I` (OpenAI baselines' policies use it).
    Orthogonal {
        /// The scale of the matrix; must be finite and positive.
        gain: f32,
    },
}

/// The shape of a dense network: `input -> hidden[0] -> ... -> output`.
///
/// Every hidden layer applies `activation`; the last layer applies
/// `output_activation`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MlpConfig {
    /// Width of the input. Default 14 (Hopper's 11 observations + 3 actions,
    /// the RED release's RND input).
    pub input: usize,
    /// Widths of the hidden layers, in order; may be empty (a linear or
    /// single-layer model). Default `[128]`: the release's RND predictor.
    pub hidden: Vec<usize>,
    /// Width of the output. Default 128: the release's RND output.
    pub output: usize,
    /// Activation of every hidden layer. Default leaky relu (slope 0.2), the
    /// release's RND activation.
    pub activation: Activation,
    /// Activation of the output layer. Default identity (linear output).
    pub output_activation: Activation,
    /// Weight initialiser. Default Glorot-uniform, TensorFlow's dense default
    /// used by the release.
    pub init: Init,
}

impl Default for MlpConfig {
    fn default() -> Self {
        MlpConfig {
            input: 14,
            hidden: vec![128],
            output: 128,
            activation: Activation::LeakyRelu,
            output_activation: Activation::Identity,
            init: Init::GlorotUniform,
        }
    }
}

impl MlpConfig {
    /// A config with the given widths, leaky relu hidden layers, linear
    /// output and Glorot-uniform weights.
    pub fn new(input: usize, hidden: &[usize], output: usize) -> Self {
        MlpConfig {
            input,
            hidden: hidden.to_vec(),
            output,
            ..MlpConfig::default()
        }
    }

    /// Sets the hidden activation (builder style).
    pub fn with_activation(mut self, activation: Activation) -> Self {
        self.activation = activation;
        self
    }

    /// Sets the output activation (builder style).
    pub fn with_output_activation(mut self, activation: Activation) -> Self {
        self.output_activation = activation;
        self
    }

    /// Sets the initialiser (builder style).
    pub fn with_init(mut self, init: Init) -> Self {
        self.init = init;
        self
    }

    /// Layer widths from input to output: `[input, hidden.., output]`.
    pub fn widths(&self) -> Vec<usize> {
        let mut w = Vec::with_capacity(self.hidden.len() + 2);
        w.push(self.input);
        w.extend_from_slice(&self.hidden);
        w.push(self.output);
        w
    }

    /// Checks the config.
    ///
    /// # Errors
    /// [`Error::InvalidConfig`] naming the field when a width is zero (`input`,
    /// `hidden[i]`, `output`) or the orthogonal gain is not finite and
    /// positive (`init.gain`).
    pub fn validate(&self) -> Result<()> {
        if self.input == 0 {
            return Err(Error::config("input", "the input width must be at least 1"));
        }
        for (i, &h) in self.hidden.iter().enumerate() {
            if h == 0 {
                return Err(Error::config(
                    format!("hidden[{i}]"),
                    "a hidden layer width must be at least 1 (remove the entry for fewer layers)",
                ));
            }
        }
        if self.output == 0 {
            return Err(Error::config(
                "output",
                "the output width must be at least 1",
            ));
        }
        if let Init::Orthogonal { gain } = self.init
            && !(gain.is_finite() && gain > 0.0)
        {
            return Err(Error::config(
                "init.gain",
                format!("the orthogonal gain must be finite and positive, got {gain}"),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field_of(e: Error) -> String {
        match e {
            Error::InvalidConfig { field, .. } => field,
            other => panic!("expected InvalidConfig, got {other:?}"),
        }
    }

    #[test]
    fn default_is_the_release_rnd_predictor_and_valid() {
        let c = MlpConfig::default();
        c.validate().unwrap();
        assert_eq!(c.widths(), vec![14, 128, 128]);
    }

    #[test]
    fn validate_names_the_bad_field() {
        assert_eq!(
            field_of(MlpConfig::new(0, &[4], 1).validate().unwrap_err()),
            "input"
        );
        assert_eq!(
            field_of(MlpConfig::new(3, &[4, 0], 1).validate().unwrap_err()),
            "hidden[1]"
        );
        assert_eq!(
            field_of(MlpConfig::new(3, &[4], 0).validate().unwrap_err()),
            "output"
        );
        for gain in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let c = MlpConfig::new(3, &[4], 2).with_init(Init::Orthogonal { gain });
            assert_eq!(field_of(c.validate().unwrap_err()), "init.gain");
        }
        let msg = MlpConfig::new(3, &[4, 0], 1)
            .validate()
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("hidden[1]") && msg.contains("at least 1"),
            "{msg}"
        );
        MlpConfig::new(3, &[], 1).validate().unwrap();
    }

    #[test]
    fn serde_defaults_and_unknown_fields() {
        let c: MlpConfig = serde_json::from_str(r#"{"input": 11, "output": 3}"#).unwrap();
        assert_eq!(c.hidden, vec![128]);
        assert_eq!(c.init, Init::GlorotUniform);
        let c: MlpConfig = serde_json::from_str(
            r#"{"init": {"orthogonal": {"gain": 1.5}}, "activation": "tanh"}"#,
        )
        .unwrap();
        assert_eq!(c.init, Init::Orthogonal { gain: 1.5 });
        assert_eq!(c.activation, Activation::Tanh);
        assert!(serde_json::from_str::<MlpConfig>(r#"{"inputs": 3}"#).is_err());
    }
}
