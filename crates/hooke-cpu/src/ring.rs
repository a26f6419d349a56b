//! Scatter's spring forces during a sweep, in a buffer whose pages repeat a small ring.
//!
//! A sweep over scatter's blocks (see `blocks`) writes each block's spring forces and sums
//! them at its vertices a few blocks later, then overwrites them at the next step: at any
//! moment a band needs only the forces of the last few blocks of each step. In a buffer as
//! large as the mesh's springs (12 bytes a spring on a grid, 151 MB at 2048^2), every sweep
//! still reads each line from memory before writing it and writes it back after: by our count
//! about as many bytes as the rest of the sweep moves. A [`ForceRing`] is a buffer of the same size
//! whose pages, inside each band's interior, map cyclically onto a few physical pages: the
//! kernels index it exactly as the plain buffer, and its lines stay in the caches.
//!
//! Pages where two bands meet, and the zero row past the springs' that padding entries read,
//! keep pages of their own. Linux only (`memfd_create`, `mmap` with `MAP_FIXED`); elsewhere, or
//! if the system refuses, sweeps use the plain buffer. The rings are a shared file, so a
//! process forked from the one that mapped them maps its own before it sweeps.

use std::ops::Range;

/// A buffer of `arrays` arrays of equal size whose pages inside each of some byte ranges
/// repeat a ring of physical pages (see the module docs).
pub(crate) struct ForceRing {
    arrays: Vec<Mapping>,
    /// The process that mapped it: a forked child shares its ring pages with the parent.
    process: u32,
}

/// One array's address range, unmapped on drop. (Elsewhere than on Linux none is made.)
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
struct Mapping {
    base: *mut u8,
    len: usize,
}

// SAFETY: a mapping is plain memory owned by its `ForceRing`; the sweep's schedule decides
// which thread touches which bytes (see `blocks`), as for the plain buffer.
unsafe impl Send for Mapping {}
unsafe impl Sync for Mapping {}

impl ForceRing {
    /// `arrays` arrays of `bytes` bytes each. In each array, the pages inside each range of
    /// `rings` repeat a ring of physical pages of their own, enough of them that bytes in use
    /// at once never share one as long as they lie within `ring_bytes` of each other; the
    /// other pages are ordinary memory. All read zero until written. `None` where the system
    /// cannot map it.
    pub(crate) fn new(
        arrays: usize,
        bytes: usize,
        rings: &[Range<usize>],
        ring_bytes: usize,
    ) -> Option<Self> {
        let arrays = (0..arrays)
            .map(|_| Mapping::new(bytes, rings, ring_bytes))
            .collect::<Option<Vec<_>>>()?;
        Some(Self {
            arrays,
            process: std::process::id(),
        })
    }

    /// Whether this process mapped it. A process forked after the mapping shares the rings'
    /// pages with its parent (they are a shared file), so it must map its own before a sweep.
    pub(crate) fn is_this_process(&self) -> bool {
        self.process == std::process::id()
    }

    /// The start of array `array`: `bytes` bytes, readable and writable, zero where never
    /// written.
    pub(crate) fn base(&self, array: usize) -> *mut u8 {
        self.arrays[array].base
    }
}

#[cfg(target_os = "linux")]
impl Mapping {
    fn new(bytes: usize, rings: &[Range<usize>], ring_bytes: usize) -> Option<Self> {
        // SAFETY: sysconf has no preconditions.
        let page = usize::try_from(unsafe { libc::sysconf(libc::_SC_PAGESIZE) }).ok()?;
        let len = bytes.max(1).div_ceil(page) * page;
        // Bytes within `ring_bytes` of each other lie on at most this many pages.
        let ring_pages = ring_bytes.div_ceil(page) + 1;
        // SAFETY: a fresh private anonymous mapping; no existing memory is affected.
        let base = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            )
        };
        if base == libc::MAP_FAILED {
            return None;
        }
        let mapping = Self {
            base: base.cast(),
            len,
        };
        for range in rings {
            // Whole pages inside the range only: a page it shares stays a page of its own.
            let pages = range.start.div_ceil(page)..(range.end.min(bytes) / page);
            if pages.len() > ring_pages {
                mapping.map_ring(pages, ring_pages, page)?;
            }
        }
        Some(mapping)
    }

    /// Maps `pages` cyclically onto a new ring of `ring_pages` pages.
    fn map_ring(&self, pages: Range<usize>, ring_pages: usize, page: usize) -> Option<()> {
        // SAFETY: a new anonymous file; the name is a valid C string.
        let fd = unsafe { libc::memfd_create(c"hooke-forces".as_ptr(), libc::MFD_CLOEXEC) };
        if fd < 0 {
            return None;
        }
        let size = libc::off_t::try_from(ring_pages * page).ok();
        // SAFETY: `fd` is the file just created.
        let sized = size.is_some_and(|size| unsafe { libc::ftruncate(fd, size) } == 0);
        let mut mapped = sized;
        let mut at = pages.start;
        while mapped && at < pages.end {
            let count = ring_pages.min(pages.end - at);
            // SAFETY: the pages `at..at + count` lie inside this mapping (`pages` is within
            // `len`), which owns them; MAP_FIXED replaces them with the ring's first pages.
            let ring = unsafe {
                libc::mmap(
                    self.base.add(at * page).cast(),
                    count * page,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_SHARED | libc::MAP_FIXED,
                    fd,
                    0,
                )
            };
            mapped = ring != libc::MAP_FAILED;
            at += count;
        }
        // SAFETY: `fd` is ours; the mappings keep the file alive.
        unsafe { libc::close(fd) };
        mapped.then_some(())
    }
}

#[cfg(not(target_os = "linux"))]
impl Mapping {
    fn new(_bytes: usize, _rings: &[Range<usize>], _ring_bytes: usize) -> Option<Self> {
        None
    }
}

impl Drop for Mapping {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        // SAFETY: `base..base + len` is this mapping's, and nothing uses it any more.
        unsafe {
            libc::munmap(self.base.cast(), self.len);
        }
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    #[test]
    fn pages_inside_ring_ranges_repeat_their_ring_and_others_keep_their_own() {
        let page = usize::try_from(unsafe { libc::sysconf(libc::_SC_PAGESIZE) }).unwrap();
        // 14 pages; pages 2..8 repeat one ring of 2 pages (bytes within a page of each other
        // lie on 2 pages at most) and 10..13 another (the ranges' ragged ends round in); 13 is
        // left out, as the page holding the zero row is.
        let rings = [2 * page - 5..8 * page + 7, 10 * page..13 * page + 1];
        let ring = ForceRing::new(1, 14 * page, &rings, page).expect("Linux maps rings");
        let base = ring.base(0);
        let at = |p: usize| unsafe { base.add(p * page + 64) };
        for p in 0..14 {
            unsafe { *at(p) = p as u8 + 1 };
        }
        let read = |p: usize| unsafe { *at(p) };
        // Outside the rings: each page its own. Inside: the last write to each slot of its ring.
        let pages: [u8; 14] = std::array::from_fn(read);
        assert_eq!(pages, [1, 2, 7, 8, 7, 8, 7, 8, 9, 10, 13, 12, 13, 14]);
        assert!(ring.is_this_process());
    }

    #[test]
    fn a_forked_process_knows_the_ring_is_not_its_own() {
        let page = usize::try_from(unsafe { libc::sysconf(libc::_SC_PAGESIZE) }).unwrap();
        let pages = 0..4 * page;
        let ring = ForceRing::new(1, 4 * page, std::slice::from_ref(&pages), page)
            .expect("Linux maps rings");
        // SAFETY: the child only asks for its process id and exits at once.
        match unsafe { libc::fork() } {
            0 => unsafe { libc::_exit(i32::from(ring.is_this_process())) },
            child => {
                assert!(child > 0, "fork failed");
                let mut status = 0;
                assert_eq!(unsafe { libc::waitpid(child, &mut status, 0) }, child);
                assert!(libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0);
                assert!(ring.is_this_process());
            }
        }
    }
}
