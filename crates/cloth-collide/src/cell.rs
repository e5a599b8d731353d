//! The grid cell of a coordinate, shared by the voxel hash and the box grid.

/// `floor(x / edge)` as an integer, the same as `(x / edge).floor() as i64`
/// for every input (NaN gives 0, values beyond `i64` saturate), without
/// the call to the C library's `floor` that the baseline x86-64 target
/// makes (it has no rounding instruction before SSE4.1): the searches
/// take cells for every point and box corner of every step.
#[inline]
pub(crate) fn cell_index(x: f64, edge: f64) -> i64 {
    let q = x / edge;
    let t = q as i64;
    // `as` truncates towards zero; below zero a fraction needs one less.
    if (t as f64) > q { t.saturating_sub(1) } else { t }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_index_is_floor_of_the_quotient_for_every_kind_of_input() {
        let edges = [0.016, 0.006, 1.0, 1e-9];
        let mut xs = vec![0.0, -0.0, 1e-300, -1e-300, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 9.3e18, -9.3e18];
        for k in -2000..2000 {
            let x = k as f64 * 0.001_37;
            xs.extend([x, x.next_up(), x.next_down()]);
        }
        for edge in edges {
            for &x in &xs {
                // Multiples of the edge, exactly on a cell's border.
                for y in [x, (x / edge).round() * edge] {
                    assert_eq!(cell_index(y, edge), (y / edge).floor() as i64, "x = {y}, edge = {edge}");
                }
            }
        }
    }
}
