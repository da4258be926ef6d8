//! Savitzky–Golay smoothing (least-squares polynomial fit over a sliding window), used to
//! smooth the virtual root's trajectory as in Holden's database builder (window 31 frames for
//! position, 61 for facing, cubic; the ends are fitted on the first/last full window, like
//! scipy's `mode='interp'`).

/// Smooths `values` (a sequence of `dim`-vectors, frame-major) in place with a window of
/// `window` frames (made odd and shrunk to fit short sequences) and polynomial `order`.
/// Sequences too short for a fit are left unchanged.
pub fn savitzky_golay(values: &mut [f64], dim: usize, window: usize, order: usize) {
    let len = values.len() / dim;
    let mut window = window.min(len);
    if window.is_multiple_of(2) {
        window = window.saturating_sub(1);
    }
    if window < order + 2 {
        return;
    }
    let half = window / 2;
    // weights[t][i]: the fitted polynomial's value at window position t, as a linear
    // combination of the window's samples i. Cached: every clip uses the same few windows.
    type Weights = std::rc::Rc<Vec<Vec<f64>>>;
    thread_local! {
        static CACHE: std::cell::RefCell<std::collections::HashMap<(usize, usize), Weights>> = Default::default();
    }
    let weights = CACHE.with(|c| {
        c.borrow_mut()
            .entry((window, order))
            .or_insert_with(|| std::rc::Rc::new((0..window).map(|t| fit_weights(window, order, t)).collect()))
            .clone()
    });
    let source = values.to_vec();
    for frame in 0..len {
        let start = frame.saturating_sub(half).min(len - window);
        let w = &weights[frame - start];
        for d in 0..dim {
            values[frame * dim + d] = (0..window).map(|i| w[i] * source[(start + i) * dim + d]).sum();
        }
    }
}

/// Weights that evaluate, at sample `t` of a `window`-long window, the least-squares
/// polynomial of `order` through the window: row `t` of `A (AᵀA)⁻¹ Aᵀ` with A the
/// Vandermonde matrix of positions scaled to [-1, 1] (for conditioning).
fn fit_weights(window: usize, order: usize, t: usize) -> Vec<f64> {
    let n = order + 1;
    let half = (window / 2) as f64;
    let x = |i: usize| (i as f64 - half) / half;
    let powers = |v: f64| (0..n).map(move |k| v.powi(k as i32));
    // Normal matrix AᵀA, then solve (AᵀA) c = a_t for c; weight_i = A_i · c.
    let mut m = vec![vec![0.0; n + 1]; n];
    for i in 0..window {
        let p: Vec<f64> = powers(x(i)).collect();
        for r in 0..n {
            for c in 0..n {
                m[r][c] += p[r] * p[c];
            }
        }
    }
    for (r, v) in powers(x(t)).enumerate() {
        m[r][n] = v;
    }
    // Gauss–Jordan with partial pivoting on an (order+1)² system.
    for col in 0..n {
        let pivot = (col..n).max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs())).unwrap();
        m.swap(col, pivot);
        for r in 0..n {
            if r != col {
                let f = m[r][col] / m[col][col];
                for c in col..=n {
                    m[r][c] -= f * m[col][c];
                }
            }
        }
    }
    let coeffs: Vec<f64> = (0..n).map(|r| m[r][n] / m[r][r]).collect();
    (0..window).map(|i| powers(x(i)).zip(&coeffs).map(|(p, c)| p * c).sum()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubic_is_reproduced_exactly_even_at_the_ends() {
        let f = |t: f64| 0.5 - 2.0 * t + 0.3 * t * t - 0.01 * t * t * t;
        let mut v: Vec<f64> = (0..100).map(|i| f(i as f64)).collect();
        savitzky_golay(&mut v, 1, 31, 3);
        for (i, x) in v.iter().enumerate() {
            assert!((x - f(i as f64)).abs() < 1e-6, "frame {i}: {x} vs {}", f(i as f64));
        }
    }

    #[test]
    fn reduces_noise_and_handles_short_input() {
        let mut v: Vec<f64> = (0..200).map(|i| if i % 2 == 0 { 1.0 } else { -1.0 }).collect();
        savitzky_golay(&mut v, 1, 31, 3);
        assert!(v[20..180].iter().all(|x| x.abs() < 0.1));
        let mut short = vec![1.0, 5.0, 2.0];
        savitzky_golay(&mut short, 1, 31, 3);
        assert_eq!(short, vec![1.0, 5.0, 2.0]);
    }
}
