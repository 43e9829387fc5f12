//! Element-wise activation functions and their derivatives.

use serde::{Deserialize, Serialize};

/// Slope of [`Activation::LeakyRelu`] for negative inputs: 0.2, the default
/// of TensorFlow's `tf.nn.leaky_relu`, which the RED release uses.
pub const LEAKY_RELU_SLOPE: f32 = 0.2;

/// An element-wise activation applied after a dense layer.
///
/// Serialised in snake case: `"relu"`, `"leaky_relu"`, `"tanh"`, `"identity"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Activation {
    /// `max(0, z)`; derivative 0 at `z = 0`.
    Relu,
    /// `z` for `z > 0`, else `0.2 z` ([`LEAKY_RELU_SLOPE`]).
    LeakyRelu,
    /// `tanh(z)`.
    Tanh,
    /// `z` (a linear layer).
    Identity,
}

impl Activation {
    /// The activation of one value.
    #[inline]
    pub fn apply(self, z: f32) -> f32 {
        match self {
            Activation::Relu => z.max(0.0),
            Activation::LeakyRelu => {
                if z > 0.0 {
                    z
                } else {
                    LEAKY_RELU_SLOPE * z
                }
            }
            Activation::Tanh => z.tanh(),
            Activation::Identity => z,
        }
    }

    /// The derivative at the pre-activation `z`.
    #[inline]
    pub fn derivative(self, z: f32) -> f32 {
        match self {
            Activation::Relu => {
                if z > 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
            Activation::LeakyRelu => {
                if z > 0.0 {
                    1.0
                } else {
                    LEAKY_RELU_SLOPE
                }
            }
            Activation::Tanh => {
                let t = z.tanh();
                1.0 - t * t
            }
            Activation::Identity => 1.0,
        }
    }

    /// The derivative expressed through the activation's OUTPUT `a = f(z)`.
    ///
    /// For these four functions the derivative is an exact function of the
    /// output (`a > 0` exactly when `z > 0` for relu and leaky relu, and
    /// `tanh'(z) = 1 - tanh(z)^2`), so tapes keep only layer outputs and
    /// backward/jvp need no second `tanh`. For relu, `a = 0` gives 0 whether
    /// `z` was 0 or negative, the same convention as [`Activation::derivative`].
    #[inline]
    pub fn derivative_from_output(self, a: f32) -> f32 {
        match self {
            Activation::Relu => {
                if a > 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
            Activation::LeakyRelu => {
                if a > 0.0 {
                    1.0
                } else {
                    LEAKY_RELU_SLOPE
                }
            }
            Activation::Tanh => 1.0 - a * a,
            Activation::Identity => 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [Activation; 4] = [
        Activation::Relu,
        Activation::LeakyRelu,
        Activation::Tanh,
        Activation::Identity,
    ];

    #[test]
    fn derivative_matches_finite_differences_away_from_kinks() {
        for act in ALL {
            for &z in &[-2.5f32, -0.7, -0.1, 0.1, 0.4, 1.3, 3.0] {
                let h = 1e-3f64;
                let f = |x: f64| act.apply(x as f32) as f64;
                let fd = (f(z as f64 + h) - f(z as f64 - h)) / (2.0 * h);
                let d = act.derivative(z) as f64;
                assert!((fd - d).abs() < 2e-3, "{act:?} at {z}: fd {fd} vs {d}");
                let d_out = act.derivative_from_output(act.apply(z)) as f64;
                assert!(
                    (d_out - d).abs() < 1e-6,
                    "{act:?} at {z}: from output {d_out} vs {d}"
                );
            }
        }
    }

    #[test]
    fn leaky_relu_uses_tensorflow_slope() {
        assert_eq!(Activation::LeakyRelu.apply(-1.0), -0.2);
        assert_eq!(Activation::LeakyRelu.apply(2.0), 2.0);
        assert_eq!(Activation::Relu.apply(-1.0), 0.0);
        assert_eq!(Activation::Relu.derivative(0.0), 0.0);
    }

    #[test]
    fn serde_names_are_snake_case() {
        assert_eq!(
            serde_json::to_string(&Activation::LeakyRelu).unwrap(),
            "\"leaky_relu\""
        );
        let a: Activation = serde_json::from_str("\"tanh\"").unwrap();
        assert_eq!(a, Activation::Tanh);
    }
}
