//! Distributions the tests of the calibration and the diagnosis decide with:
//! the normal, Student's t, F and chi-square, the incomplete beta and gamma
//! functions under them. Pure: numbers in, numbers out.

/// Standard normal quantile (Acklam's rational approximation, |error| < 1.2e-9).
#[allow(clippy::excessive_precision)]
pub fn normal_quantile(p: f64) -> f64 {
    let a = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383577518672690e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    let b = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    let c = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    let d = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let pl = 0.02425;
    if p < pl {
        let q = (-2.0 * p.ln()).sqrt();
        (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5])
            / ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0)
    } else if p <= 1.0 - pl {
        let q = p - 0.5;
        let r = q * q;
        (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q
            / (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0)
    } else {
        -normal_quantile(1.0 - p)
    }
}

/// Student t quantile by the Cornish-Fisher expansion about the normal one
/// (good to a few per cent for 4 or more degrees of freedom).
pub fn t_quantile(p: f64, dof: f64) -> f64 {
    let z = normal_quantile(p);
    let v = dof.max(1.0);
    z + (z.powi(3) + z) / (4.0 * v)
        + (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / (96.0 * v * v)
        + (3.0 * z.powi(7) + 19.0 * z.powi(5) + 17.0 * z.powi(3) - 15.0 * z) / (384.0 * v.powi(3))
}

/// The chi-square quantile at `p` with `dof` degrees of freedom (the
/// Wilson-Hilferty cube; within about 1 % from 2 degrees of freedom).
pub fn chi_square_quantile(p: f64, dof: f64) -> f64 {
    let k = dof.max(1e-9);
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + normal_quantile(p) * a.sqrt()).powi(3)
}

/// The point in [lo, hi] where `below` turns false (200 halvings) (`below` true below it).
pub fn bisect(mut lo: f64, mut hi: f64, below: impl Fn(f64) -> bool) -> f64 {
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if below(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The distribution function at `r` of the length of a three-dimensional
/// standard normal vector shifted by `mu` (the root of a noncentral
/// chi-square with three degrees of freedom).
pub fn noncentral_chi3_cdf(r: f64, mu: f64) -> f64 {
    let phi = |x: f64| (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt();
    if mu < 1e-6 {
        // The central chi: 2 Phi(r) - 1 - 2 r phi(r).
        return normal_cdf(r) - normal_cdf(-r) - 2.0 * r * phi(r);
    }
    normal_cdf(r - mu) - normal_cdf(-r - mu) - (phi(r - mu) - phi(r + mu)) / mu
}

/// The standard normal distribution function (erfc of Numerical Recipes,
/// relative error below 1.2e-7).
pub fn normal_cdf(x: f64) -> f64 {
    let z = x.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let erfc = t * poly.exp();
    if x >= 0.0 {
        1.0 - 0.5 * erfc
    } else {
        0.5 * erfc
    }
}

/// The upper tail of the F distribution with `d1` and `d2` degrees of
/// freedom at `f`.
pub fn f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    if f <= 0.0 {
        return 1.0;
    }
    beta_regularized(d2 / (d2 + d1 * f), 0.5 * d2, 0.5 * d1)
}

/// The |t| with `dof` degrees of freedom whose two-sided tail is `p`.
pub fn t_equivalent(p: f64, dof: f64) -> f64 {
    let v = dof.max(1.0);
    let p = p.clamp(1e-300, 1.0);
    // The two-sided tail at t is I_x(v / 2, 1 / 2) with x = v / (v + t^2),
    // increasing in x: bisect on ln x.
    let ln_x = bisect(-700.0, 0.0, |l| beta_regularized(l.exp(), 0.5 * v, 0.5) < p);
    let x = ln_x.exp();
    (v * (1.0 - x) / x).max(0.0).sqrt()
}

/// ln Gamma(x), x > 0 (Lanczos, g = 7).
#[allow(clippy::excessive_precision)]
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_93,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_13,
        -176.615_029_162_140_59,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_571_6e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let sum = C[1..]
        .iter()
        .enumerate()
        .fold(C[0], |s, (i, c)| s + c / (x + i as f64 + 1.0));
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + sum.ln()
}

/// The regularized incomplete beta function I_x(a, b) (continued fraction,
/// Numerical Recipes' betacf).
pub fn beta_regularized(x: f64, a: f64, b: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let front =
        (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_fraction(x, a, b) / a
    } else {
        1.0 - front * beta_fraction(1.0 - x, b, a) / b
    }
}

fn beta_fraction(x: f64, a: f64, b: f64) -> f64 {
    let tiny = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < tiny {
        d = tiny;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..300 {
        let m = m as f64;
        let m2 = 2.0 * m;
        for aa in [
            m * (b - m) * x / ((qam + m2) * (a + m2)),
            -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2)),
        ] {
            d = 1.0 + aa * d;
            if d.abs() < tiny {
                d = tiny;
            }
            c = 1.0 + aa / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            h *= d * c;
        }
        // The last factor of the pair.
        if (d * c - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_match_tables() {
        assert!((normal_quantile(0.975) - 1.959964).abs() < 1e-5);
        assert!((normal_quantile(0.995) - 2.575829).abs() < 1e-5);
        // t(0.975, 10) = 2.228, t(0.995, 20) = 2.845.
        assert!((t_quantile(0.975, 10.0) - 2.228).abs() < 0.01);
        assert!((t_quantile(0.995, 20.0) - 2.845).abs() < 0.01);
        // The information limit's critical value: 12 segments, 5 % over
        // 12 effects two-sided (t(0.99792, 11) = 3.60).
        assert!((t_quantile(1.0 - 0.025 / 12.0, 11.0) - 3.60).abs() < 0.05);
    }

    #[test]
    fn the_joint_tests_distributions_match_their_tables() {
        // Student t, two-sided 5 % with 10 degrees of freedom: 2.228.
        assert!((t_equivalent(0.05, 10.0) - 2.2281).abs() < 1e-3);
        // F(3, 10) upper 5 %: 3.708.
        assert!((f_sf(3.7083, 3.0, 10.0) - 0.05).abs() < 1e-4);
        // The central chi with three degrees of freedom: chi^2 = 7.815 at
        // the upper 5 %, both branches alike.
        let r = 7.8147_f64.sqrt();
        assert!((1.0 - noncentral_chi3_cdf(r, 0.0) - 0.05).abs() < 1e-4);
        assert!((noncentral_chi3_cdf(r, 1e-5) - noncentral_chi3_cdf(r, 0.0)).abs() < 1e-4);
        // One term: Hotelling's reference is the t's.
        let p = f_sf(2.5_f64.powi(2), 1.0, 9.0);
        assert!((t_equivalent(p, 9.0) - 2.5).abs() < 1e-6);
        // A tail far beyond the doubles' resolution of 1 - p.
        let far = t_equivalent(1e-30, 12.0);
        assert!(far.is_finite() && far > 20.0, "{far}");
    }

    #[test]
    fn the_chi_square_quantile_matches_its_table() {
        // chi^2(0.95) with 2, 4 and 10 degrees of freedom: 5.991, 9.488, 18.307.
        for (k, q) in [(2.0, 5.991), (4.0, 9.488), (10.0, 18.307)] {
            let x = chi_square_quantile(0.95, k);
            assert!((x / q - 1.0).abs() < 0.01, "{k}: {x}");
        }
    }

    #[test]
    fn the_normal_distribution_function_inverts_its_quantile() {
        for p in [1e-6, 0.01, 0.3, 0.5, 0.9, 0.999] {
            assert!(
                (normal_cdf(normal_quantile(p)) - p).abs() < 1e-6 * p.max(0.01),
                "{p}"
            );
        }
    }
}
