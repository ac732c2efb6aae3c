//! The fixed row blocks that [`super::dense::Dense`] and [`super::mlp::FusedMlp`] walk:
//! [`ROW_BLOCK`] rows each (the last one shorter), on rayon when the work is large
//! enough, with per-block partial sums added in block order so that results do not
//! depend on the number of threads.

use rayon::prelude::*;

use crate::Float;
use crate::float::ROW_BLOCK;

/// Splits `data` into consecutive per-block slices of `per_row` values per row for
/// `m` rows in blocks of [`ROW_BLOCK`] (empty slices when `per_row` is 0).
pub(crate) fn row_blocks<T>(mut data: &mut [T], per_row: usize, m: usize) -> Vec<&mut [T]> {
    (0..m.div_ceil(ROW_BLOCK))
        .map(|i| {
            let rows = ROW_BLOCK.min(m - i * ROW_BLOCK);
            let (head, tail) = std::mem::take(&mut data).split_at_mut(rows * per_row);
            data = tail;
            head
        })
        .collect()
}

/// Runs `f(block index, item)` over the items, in parallel when `parallel`; returns
/// the results in block order.
pub(crate) fn map_blocks<I: Send, R: Send>(
    items: Vec<I>,
    parallel: bool,
    f: impl Fn(usize, I) -> R + Sync + Send,
) -> Vec<R> {
    if parallel {
        items
            .into_par_iter()
            .enumerate()
            .map(|(i, x)| f(i, x))
            .collect()
    } else {
        items
            .into_iter()
            .enumerate()
            .map(|(i, x)| f(i, x))
            .collect()
    }
}

/// Adds per-block partial sums in block order (`None` when there is no block).
pub(crate) fn sum_in_order<T: Float>(parts: impl Iterator<Item = Vec<T>>) -> Option<Vec<T>> {
    parts.reduce(|mut acc, p| {
        acc.iter_mut().zip(&p).for_each(|(a, &b)| *a += b);
        acc
    })
}
