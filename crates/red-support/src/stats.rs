//! Small statistics used to calibrate rewards and to judge estimators:
//! quantiles, ROC AUC and Spearman rank correlation.

/// The `q`-quantile (`0 <= q <= 1`) of `values` with linear interpolation
/// between order statistics (NumPy's default, "type 7"). NaN for an empty
/// slice.
pub fn quantile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    quantile_sorted(&v, q)
}

/// [`quantile`] of values already sorted ascending.
pub fn quantile_sorted(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    let t = pos - lo as f64;
    sorted[lo] + t * (sorted[hi] - sorted[lo])
}

/// One line of `name`'s mean, min, quartiles, 0.1, 0.9 and 0.99
/// quantiles and max, of values sorted ascending (not empty).
pub fn summary_line(name: &str, sorted: &[f64]) -> String {
    let q = |p| quantile_sorted(sorted, p);
    format!(
        "{name:<8} mean {:.4e}  min {:.4e}  q10 {:.4e}  q25 {:.4e}  median {:.4e}  q75 {:.4e}  q90 {:.4e}  q99 {:.4e}  max {:.4e}",
        mean(sorted),
        sorted[0],
        q(0.1),
        q(0.25),
        q(0.5),
        q(0.75),
        q(0.9),
        q(0.99),
        sorted[sorted.len() - 1]
    )
}

/// Mean of `values` (NaN when empty).
pub fn mean(values: &[f64]) -> f64 {
    values.iter().sum::<f64>() / values.len() as f64
}

/// Ranks of `values` starting at 1, ties given their average rank.
pub fn ranks(values: &[f64]) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..values.len()).collect();
    idx.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut r = vec![0.0; values.len()];
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && values[idx[j + 1]] == values[idx[i]] {
            j += 1;
        }
        let avg = (i + j) as f64 / 2.0 + 1.0;
        for k in i..=j {
            r[idx[k]] = avg;
        }
        i = j + 1;
    }
    r
}

/// ROC AUC of a score that should be LOW on `negatives` and HIGH on
/// `positives`: the probability that a random positive scores above a
/// random negative, ties counting one half (the Mann-Whitney U statistic
/// divided by the number of pairs). NaN if either set is empty.
pub fn roc_auc(negatives: &[f64], positives: &[f64]) -> f64 {
    let (n0, n1) = (negatives.len(), positives.len());
    if n0 == 0 || n1 == 0 {
        return f64::NAN;
    }
    let all: Vec<f64> = negatives.iter().chain(positives).copied().collect();
    let r = ranks(&all);
    let rank_sum_pos: f64 = r[n0..].iter().sum();
    let u = rank_sum_pos - (n1 * (n1 + 1)) as f64 / 2.0;
    u / (n0 * n1) as f64
}

/// Spearman's rank correlation of two equally long samples (Pearson's
/// correlation of their average ranks).
pub fn spearman(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "spearman: samples differ in length");
    let (ra, rb) = (ranks(a), ranks(b));
    let (ma, mb) = (mean(&ra), mean(&rb));
    let mut sab = 0.0;
    let mut saa = 0.0;
    let mut sbb = 0.0;
    for (x, y) in ra.iter().zip(&rb) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantile_interpolates_like_numpy() {
        // numpy.quantile([1, 2, 3, 4], [0, 0.25, 0.9, 1]) = [1, 1.75, 3.7, 4]
        let v = [4.0, 1.0, 3.0, 2.0];
        assert_eq!(quantile(&v, 0.0), 1.0);
        assert!((quantile(&v, 0.25) - 1.75).abs() < 1e-12);
        assert!((quantile(&v, 0.9) - 3.7).abs() < 1e-12);
        assert_eq!(quantile(&v, 1.0), 4.0);
    }

    #[test]
    fn auc_matches_a_hand_count() {
        // Pairs (neg, pos): (1,2) win, (1,0.5) loss, (3,2) loss, (3,0.5)
        // loss, ties none -> 1/4; add a tie (2 vs 2) for 1/2 more.
        assert!((roc_auc(&[1.0, 3.0], &[2.0, 0.5]) - 0.25).abs() < 1e-12);
        assert!((roc_auc(&[2.0], &[2.0]) - 0.5).abs() < 1e-12);
        assert_eq!(roc_auc(&[0.0, 0.1], &[1.0, 2.0, 3.0]), 1.0);
    }

    #[test]
    fn spearman_is_one_for_monotone_and_minus_one_for_reversed() {
        let a = [1.0, 2.0, 3.0, 10.0];
        let b = [0.1, 0.2, 5.0, 6.0];
        assert!((spearman(&a, &b) - 1.0).abs() < 1e-12);
        let c = [4.0, 3.0, 2.0, 1.0];
        assert!((spearman(&a, &c) + 1.0).abs() < 1e-12);
        assert_eq!(ranks(&[1.0, 1.0, 2.0]), vec![1.5, 1.5, 3.0]);
    }
}
