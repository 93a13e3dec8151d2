//! LSD radix sort of (u32 key, u32 value) pairs and the order-preserving
//! f32 -> u32 key map: the sorting primitives of the visibility orders. They
//! sit apart so that both orders (`sort`'s centroid sort and `mpvo`, which
//! `sort::Sorter` wraps) can use them without depending on each other.

/// Order-preserving map from f32 to u32 (ascending floats -> ascending keys).
#[inline]
pub(crate) fn float_key(x: f32) -> u32 {
    let b = x.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// Stable LSD radix sort of (key, value) pairs by key, 8 bits per pass;
/// passes whose digit is the same for every key are skipped.
pub fn radix_sort_pairs(keys: &mut Vec<u32>, values: &mut Vec<u32>, tmp_k: &mut Vec<u32>, tmp_v: &mut Vec<u32>) {
    let n = keys.len();
    debug_assert_eq!(values.len(), n);
    tmp_k.resize(n, 0);
    tmp_v.resize(n, 0);
    // All four histograms in one read of the keys.
    let mut hist = [[0usize; 256]; 4];
    for &k in keys.iter() {
        for (p, h) in hist.iter_mut().enumerate() {
            h[((k >> (8 * p)) & 0xff) as usize] += 1;
        }
    }
    for (p, h) in hist.iter().enumerate() {
        if h.contains(&n) {
            continue; // every key has the same digit: this pass would not move anything
        }
        let mut offsets = [0usize; 256];
        let mut sum = 0;
        for (o, &c) in offsets.iter_mut().zip(h.iter()) {
            *o = sum;
            sum += c;
        }
        let shift = 8 * p;
        for i in 0..n {
            let k = keys[i];
            let d = ((k >> shift) & 0xff) as usize;
            let dst = offsets[d];
            offsets[d] += 1;
            tmp_k[dst] = k;
            tmp_v[dst] = values[i];
        }
        std::mem::swap(keys, tmp_k);
        std::mem::swap(values, tmp_v);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float_keys_are_monotonic() {
        let xs = [-1e30f32, -2.0, -1.0, -0.0, 0.0, 1e-30, 1.0, 3.5, 1e30];
        for w in xs.windows(2) {
            assert!(float_key(w[0]) <= float_key(w[1]), "{} {}", w[0], w[1]);
        }
    }

    #[test]
    fn radix_matches_std_sort() {
        let mut state = 12345u64;
        let mut keys: Vec<u32> = (0..10_000)
            .map(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 33) as u32
            })
            .collect();
        let mut expected: Vec<(u32, u32)> = keys.iter().copied().zip(0..).collect();
        expected.sort_by_key(|&(k, _)| k); // stable, like LSD radix
        let mut values: Vec<u32> = (0..keys.len() as u32).collect();
        radix_sort_pairs(&mut keys, &mut values, &mut Vec::new(), &mut Vec::new());
        let got: Vec<(u32, u32)> = keys.into_iter().zip(values).collect();
        assert_eq!(got, expected);
    }
}
