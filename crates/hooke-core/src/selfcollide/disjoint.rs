//! A slice that the tasks of one parallel pass write into at once, each to elements of its
//! own, where the elements a task writes are known only as it goes (a radix sort's slots,
//! a vertex's rank among the covered ones), so the slice cannot be split into `&mut` parts
//! up front. (The radix sort handed each chunk its ranges as `&mut` slices before, which cost
//! a 16-byte slice update per entry in a table four times the size of the first-level cache:
//! two thirds of the sort's time.)

use std::marker::PhantomData;

/// Writes into a mutably borrowed slice of plain values (nothing to drop) from many threads;
/// see [`Disjoint::write`] for the one rule that makes it sound. A copy is the same writer.
#[derive(Clone, Copy)]
pub struct Disjoint<'a, T> {
    start: *mut T,
    len: usize,
    buffer: PhantomData<&'a mut [T]>,
}

// SAFETY: the writer only hands values of `T` to other threads' slots (hence `T: Send`), and
// only through `write`, whose callers promise that no two threads touch one element.
#[allow(unsafe_code)]
unsafe impl<T: Send> Sync for Disjoint<'_, T> {}

impl<'a, T: Copy> Disjoint<'a, T> {
    /// Borrows `slice` for writing until the writer (and every copy) is dropped.
    pub fn new(slice: &'a mut [T]) -> Self {
        Self {
            start: slice.as_mut_ptr(),
            len: slice.len(),
            buffer: PhantomData,
        }
    }

    /// Writes `value` at `index` (checked against the length: a wrong index panics rather
    /// than writing out of bounds).
    ///
    /// # Safety
    /// While this writer lives, no other thread may write element `index`: every caller
    /// gives each task a set of indices that no other task's set shares.
    #[inline(always)]
    #[allow(unsafe_code)]
    pub unsafe fn write(&self, index: usize, value: T) {
        assert!(index < self.len, "index {index} of {}", self.len);
        // SAFETY: in bounds (checked above); the slice is borrowed mutably for as long as
        // `self` lives, so nothing reads it meanwhile; no other thread writes this element
        // (the caller's promise).
        unsafe { self.start.add(index).write(value) };
    }
}

#[cfg(test)]
mod tests {
    use rayon::prelude::*;

    use super::*;

    #[test]
    fn tasks_writing_interleaved_indices_fill_the_whole_slice() {
        let mut out = vec![0u32; 10_000];
        let writer = Disjoint::new(&mut out);
        // Task `t` writes every index congruent to `t` mod 7: sets that no two tasks share,
        // and that no split of the slice into ranges could hand out.
        (0..7usize).into_par_iter().for_each(|t| {
            for i in (t..10_000).step_by(7) {
                // SAFETY: index `i` belongs to task `i % 7` only.
                #[allow(unsafe_code)]
                unsafe {
                    writer.write(i, (i * 3) as u32)
                };
            }
        });
        assert!(out.iter().enumerate().all(|(i, &x)| x == (i * 3) as u32));
    }

    #[test]
    #[should_panic(expected = "index 4 of 4")]
    fn an_index_past_the_end_panics() {
        let mut out = [0u8; 4];
        let writer = Disjoint::new(&mut out);
        // SAFETY: one thread.
        #[allow(unsafe_code)]
        unsafe {
            writer.write(4, 1)
        };
    }
}
