//! Items grouped by a key in `0..n`, in compressed rows: neighbour lists
//! of a matrix's graph and the per-particle lists the solvers build every
//! step (a counting sort, no allocation once the buffers have grown).

/// Items of type `T` grouped by key, each group in the items' order.
#[derive(Debug, Clone, Default)]
pub struct Buckets<T> {
    start: Vec<u32>,
    items: Vec<T>,
    fill: Vec<u32>,
}

impl<T: Copy + Default> Buckets<T> {
    /// Regroups the `(key, item)` pairs `entries` yields (called twice:
    /// once to count, once to place) over keys `0..n`.
    pub fn rebuild<I: Iterator<Item = (usize, T)>>(&mut self, n: usize, entries: impl Fn() -> I) {
        self.start.clear();
        self.start.resize(n + 1, 0);
        for (key, _) in entries() {
            self.start[key + 1] += 1;
        }
        for i in 0..n {
            self.start[i + 1] += self.start[i];
        }
        self.items.clear();
        self.items.resize(self.start[n] as usize, T::default());
        self.fill.clear();
        self.fill.extend_from_slice(&self.start[..n]);
        for (key, item) in entries() {
            self.items[self.fill[key] as usize] = item;
            self.fill[key] += 1;
        }
    }

    /// Key `i`'s items; none for a key past the last rebuild's `n`.
    pub fn of(&self, i: usize) -> &[T] {
        if self.start.len() <= i + 1 {
            return &[];
        }
        &self.items[self.start[i] as usize..self.start[i + 1] as usize]
    }

    /// Sorts each key's items (an order that does not depend on the
    /// order `entries` yielded them in).
    pub fn sort_each(&mut self)
    where
        T: Ord,
    {
        for w in self.start.windows(2) {
            self.items[w[0] as usize..w[1] as usize].sort_unstable();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn items_are_grouped_by_key_in_their_order() {
        let entries = [(2, 'a'), (0, 'b'), (2, 'c'), (3, 'd'), (0, 'e')];
        let mut b = Buckets::default();
        b.rebuild(5, || entries.iter().copied());
        assert_eq!(b.of(0), ['b', 'e']);
        assert_eq!(b.of(1), [] as [char; 0]);
        assert_eq!(b.of(2), ['a', 'c']);
        assert_eq!(b.of(3), ['d']);
        assert_eq!(b.of(4), [] as [char; 0]);
        assert_eq!(b.of(9), [] as [char; 0]);
        b.sort_each();
        assert_eq!(b.of(0), ['b', 'e']);
        b.rebuild(3, || [(1, 'q'), (0, 'z'), (1, 'p')].into_iter());
        b.sort_each();
        assert_eq!(b.of(1), ['p', 'q']);
        assert_eq!(b.of(0), ['z']);
        assert_eq!(b.of(3), [] as [char; 0]);
    }
}
