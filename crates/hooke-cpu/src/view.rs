//! Read-only views of the buffers a kernel reads at arbitrary indices: the positions (three
//! axes and, for rows gathered lane by lane, one point per vertex) and scatter's spring forces.
//!
//! They hold pointers, not slices. A sweep of several steps (see `crate::sweep`) has one
//! thread read positions around its band of vertices while another thread writes other slices
//! of the same buffer, and a scatter step block by block (`crate::blocks`) has one thread sum
//! spring forces its band has written while another writes other rows; a shared slice over the
//! whole buffer would claim that nobody writes any of it. A view reads 8 floats, or one point, at a time, and the code that makes a view over
//! memory others write (with [`Positions::from_raw`]) guarantees that none of what is read is
//! written while the view is in use.

use std::marker::PhantomData;

use crate::kernels::Soa;
use crate::layout::LANES;
use crate::simd::{Block, Point, Simd};

/// A run of `T` (floats, or points) that a kernel reads from.
#[derive(Debug)]
pub struct Run<'a, T> {
    start: *const T,
    len: usize,
    _borrow: PhantomData<&'a [T]>,
}

// Not derived: that would require `T: Clone`, and a view copies only its pointer.
impl<T> Clone for Run<'_, T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Run<'_, T> {}

// SAFETY: a view only reads, and whoever makes one over shared memory guarantees that what it
// reads is not written meanwhile (see the module docs).
unsafe impl<T> Send for Run<'_, T> {}
unsafe impl<T> Sync for Run<'_, T> {}

/// Floats that a kernel reads 8 at a time or gathers from.
pub type Floats<'a> = Run<'a, f32>;

/// One point per vertex (or spring slot), gathered lane by lane.
pub type Points<'a> = Run<'a, Point>;

impl<'a, T> Run<'a, T> {
    pub fn new(values: &'a [T]) -> Self {
        Self {
            start: values.as_ptr(),
            len: values.len(),
            _borrow: PhantomData,
        }
    }

    /// `len` values at `start`.
    ///
    /// # Safety
    /// They must stay readable for `'a`, and no thread may write any value the view is read
    /// at while it is in use.
    pub(crate) unsafe fn from_raw(start: *const T, len: usize) -> Self {
        Self {
            start,
            len,
            _borrow: PhantomData,
        }
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl<'a> Floats<'a> {
    /// The 8 floats from `first` on.
    #[inline(always)]
    pub fn run(&self, first: usize) -> &'a Block {
        assert!(first + LANES <= self.len, "run out of bounds");
        // SAFETY: in bounds (checked).
        unsafe { self.run_unchecked(first) }
    }

    /// [`Floats::run`] without the bounds check.
    ///
    /// # Safety
    /// `first + 8` must not exceed the view's length.
    #[inline(always)]
    pub unsafe fn run_unchecked(&self, first: usize) -> &'a Block {
        debug_assert!(first + LANES <= self.len, "run out of bounds");
        // SAFETY: in bounds by the caller's guarantee; not written while the view lives.
        unsafe { &*self.start.add(first).cast::<Block>() }
    }

    /// `values[index[lane] & mask]` per lane.
    ///
    /// # Safety
    /// Every masked index must be below the view's length.
    #[inline(always)]
    pub unsafe fn gather<S: Simd>(&self, simd: S, index: &[u32; LANES], mask: u32) -> S::V {
        // SAFETY: in bounds by the caller's guarantee; not written while the view lives.
        unsafe { simd.gather(self.start, index, mask) }
    }
}

impl<'a> Points<'a> {
    /// The 8 points of slice `slice`.
    #[inline(always)]
    pub fn slice(&self, slice: usize) -> &'a [Point; LANES] {
        assert!((slice + 1) * LANES <= self.len, "slice out of bounds");
        // SAFETY: in bounds (checked); not written while the view lives.
        unsafe { &*self.start.add(slice * LANES).cast::<[Point; LANES]>() }
    }

    /// The points at byte offsets `offsets[lane] & mask`, as x, y and z.
    ///
    /// # Safety
    /// Every masked offset must be a multiple of 16 below 16 times the view's length.
    #[inline(always)]
    pub unsafe fn gather_points_at<S: Simd>(
        &self,
        simd: S,
        offsets: &[u32; LANES],
        mask: u32,
    ) -> [S::V; 3] {
        // SAFETY: in bounds by the caller's guarantee; not written while the view lives.
        unsafe { simd.gather_points_at(self.start, offsets, mask) }
    }

    /// The 8 points stored from byte offset `offset`, two to a value (see
    /// [`Simd::point_pairs_run`]).
    ///
    /// # Safety
    /// `offset` must be a multiple of 16, with 8 points from it within the view.
    #[inline(always)]
    pub unsafe fn point_pairs_run<S: Simd>(&self, simd: S, offset: u32) -> [S::V; 4] {
        // SAFETY: in bounds by the caller's guarantee; not written while the view lives.
        unsafe { simd.point_pairs_run(self.start, offset) }
    }

    /// The points at byte offsets `offsets[lane] & mask`, two to a value (see
    /// [`Simd::point_pairs_at`]).
    ///
    /// # Safety
    /// Every masked offset must be a multiple of 16 below 16 times the view's length.
    #[inline(always)]
    pub unsafe fn point_pairs_at<S: Simd>(
        &self,
        simd: S,
        offsets: &[u32; LANES],
        mask: u32,
    ) -> [S::V; 4] {
        // SAFETY: in bounds by the caller's guarantee; not written while the view lives.
        unsafe { simd.point_pairs_at(self.start, offsets, mask) }
    }

    /// `points[index[lane] & mask]` per lane, as x, y and z.
    ///
    /// # Safety
    /// Every masked index must be below the view's length.
    #[inline(always)]
    pub unsafe fn gather_points<S: Simd>(
        &self,
        simd: S,
        index: &[u32; LANES],
        mask: u32,
    ) -> [S::V; 3] {
        // SAFETY: in bounds by the caller's guarantee; not written while the view lives.
        unsafe { simd.gather_points(self.start, index, mask) }
    }
}

/// The positions a kernel reads: three axes and, when its rows read them, the same as points.
#[derive(Clone, Copy, Debug)]
pub struct Positions<'a> {
    pub axes: [Floats<'a>; 3],
    pub points: Option<Points<'a>>,
}

impl<'a> Positions<'a> {
    pub fn new(positions: &'a Soa, points: Option<&'a [Point]>) -> Self {
        let [xs, ys, zs] = positions.axes();
        let axes = [xs, ys, zs].map(|axis| Floats::new(axis.as_flattened()));
        let points = points.map(Points::new);
        assert!(points.is_none_or(|p| p.len() == axes[0].len()));
        Self { axes, points }
    }

    /// A view of `blocks` blocks per axis at `axes` and, if given, as many rows of points.
    ///
    /// # Safety
    /// The memory must be readable and stay allocated for `'a`, and no thread may write any
    /// float or point that the view is read at while it is in use.
    pub unsafe fn from_raw(
        axes: [*const Block; 3],
        blocks: usize,
        points: Option<*const [Point; LANES]>,
    ) -> Self {
        let len = blocks * LANES;
        // SAFETY: the caller's guarantee.
        unsafe {
            Self {
                axes: axes.map(|axis| Floats::from_raw(axis.cast(), len)),
                points: points.map(|points| Points::from_raw(points.cast(), len)),
            }
        }
    }

    /// Slice `slice` of axis `axis`.
    #[inline(always)]
    pub fn block(&self, axis: usize, slice: usize) -> &'a Block {
        self.axes[axis].run(slice * LANES)
    }
}
