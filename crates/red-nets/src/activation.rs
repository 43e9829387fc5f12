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
            Activation::Tanh => tanh_f32(z),
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
                let t = tanh_f32(z);
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

/// `tanh` in f32, written so that compilers vectorise loops over it
/// (`f32::tanh` calls the C library once per element, which dominated a
/// tanh policy's forward pass).
///
/// `tanh(a) = E / (E + 2)` with `E = expm1(2a)` for `a = |x|`, sign restored
/// at the end. `expm1(y) = 2^n q(r) + (2^n - 1)` with `y = n ln 2 + r`,
/// `|r| <= ln 2 / 2`, and `q(r) = e^r - 1` by its degree-7 Taylor
/// polynomial (truncation 5e-9 relative). Keeping `q` without its constant
/// term keeps small arguments accurate (for `n = 0`, `E = q(2a)`), so one
/// branch-free formula covers the whole line. Largest relative error against
/// f64 `tanh` on a sweep of [-12, 12] (unit test `fast_tanh_is_accurate`):
/// below 2.5e-7, a few units in the last place. NaN propagates;
/// `tanh(+-inf) = +-1`.
#[inline(always)]
pub fn tanh_f32(x: f32) -> f32 {
    // 1.5 * 2^23: adding it rounds to an integer held in the low mantissa bits.
    const MAGIC: f32 = 12_582_912.0;
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    // ln 2 split so that n * LN2_HI is exact for the n used here (Cody-Waite).
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;

    let a = x.abs();
    // tanh(10) rounds to 1 in f32, so 2a is capped at 20 (a NaN fails the
    // comparison, passes unchanged and stays NaN).
    let y = 2.0 * a;
    let y = if y > 20.0 { 20.0 } else { y };
    let t = y * LOG2E + MAGIC;
    let n = t - MAGIC;
    let r = (y - n * LN2_HI) - n * LN2_LO;
    let q = r
        * (1.0
            + r * (0.5
                + r * (1.0 / 6.0
                    + r * (1.0 / 24.0
                        + r * (1.0 / 120.0 + r * (1.0 / 720.0 + r * (1.0 / 5040.0)))))));
    let n_int = t.to_bits().wrapping_sub(MAGIC.to_bits());
    let two_n = f32::from_bits(n_int.wrapping_add(127) << 23);
    let e = two_n * q + (two_n - 1.0);
    (e / (e + 2.0)).copysign(x)
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
    fn fast_tanh_is_accurate() {
        let mut worst_rel = 0.0f64;
        let mut worst_at = 0.0f32;
        let mut check = |x: f32| {
            let got = tanh_f32(x) as f64;
            let want = (x as f64).tanh();
            let rel = if want == 0.0 {
                got.abs()
            } else {
                ((got - want) / want).abs()
            };
            if rel > worst_rel {
                worst_rel = rel;
                worst_at = x;
            }
        };
        for i in -240_000..=240_000 {
            check(i as f32 * 5e-5);
        }
        for e in -40..4 {
            let x = 2f32.powi(e) * 1.37;
            check(x);
            check(-x);
        }
        check(0.55);
        check(0.549_999_95);
        eprintln!("tanh_f32 worst relative error {worst_rel:e} at {worst_at}");
        // About two units in the last place (f32's unit is 6e-8 relative).
        assert!(
            worst_rel < 2.5e-7,
            "worst relative error {worst_rel} at {worst_at}"
        );
        assert_eq!(tanh_f32(0.0), 0.0);
        assert!(tanh_f32(-0.0).is_sign_negative());
        assert_eq!(tanh_f32(f32::INFINITY), 1.0);
        assert_eq!(tanh_f32(f32::NEG_INFINITY), -1.0);
        assert_eq!(tanh_f32(50.0), 1.0);
        assert!(tanh_f32(f32::NAN).is_nan());
        assert!(tanh_f32(1e-30) == 1e-30);
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
