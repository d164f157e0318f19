//! A global allocator that backs large allocations with transparent huge pages (Linux).
//!
//! Why: the pipeline's large arrays (the fits' K × K normal equations, K = k², 50 MB at k = 50;
//! the bases, n × k; the restricted searches' blocks) are allocated fresh, and every 4 KiB page
//! of fresh memory costs a page fault at first touch. On the 2-core VMs we measure on that cost
//! is 1.6–5 µs per page (BENCHMARKS.md, "Fresh memory is expensive on this VM"): filling the
//! 50 MB normal equations of the k = 50 fit with zeros took ≈ 20–50 ms of their 120 ms. With `madvise(MADV_HUGEPAGE)` the
//! kernel maps 2 MiB pages where it can (`/sys/kernel/mm/transparent_hugepage/enabled` set to
//! `madvise` or `always`), one fault per 512 small pages. The arithmetic is unchanged, so every
//! result is bit for bit the same with or without it.
//!
//! Allocations of at least [`HUGE_THRESHOLD`] bytes (32 MiB) are mapped directly (`mmap`,
//! aligned to 2 MiB, `madvise(MADV_HUGEPAGE)`, released by `munmap`); smaller ones go to the
//! system allocator. Declared by the front ends (`funcorr` CLI, the Python module) with
//! `#[global_allocator] static ALLOC: funcorr::alloc::HugePageAlloc = funcorr::alloc::HugePageAlloc;`.
//! On other systems it is the system allocator. (A wrapper of a few lines rather than jemalloc or
//! mimalloc: those are C builds that would lengthen every clean build, and their huge-page
//! options are process-wide settings, not per allocation size.)

use std::alloc::{GlobalAlloc, Layout, System};

/// Allocations of at least this many bytes (32 MiB) are backed by huge pages: glibc's largest
/// mmap threshold, so the allocations below it keep glibc's reuse of freed heap memory (no fault
/// at all, where a 4 MiB threshold mapped every mid-size temporary afresh), and those above it,
/// which glibc maps fresh every time anyway, fault once per 2 MiB instead of once per 4 KiB.
pub const HUGE_THRESHOLD: usize = 32 << 20;

/// The huge page size the mappings are aligned to (2 MiB, x86-64 and aarch64 with 4 KiB pages).
#[cfg(target_os = "linux")]
const HUGE_PAGE: usize = 2 << 20;

/// The system allocator, with allocations of at least [`HUGE_THRESHOLD`] bytes in 2 MiB-aligned
/// anonymous mappings advised for transparent huge pages (module docs).
#[derive(Clone, Copy, Debug, Default)]
pub struct HugePageAlloc;

#[cfg(target_os = "linux")]
mod imp {
    use super::HUGE_PAGE;

    /// `size` rounded up to whole huge pages; `None` on overflow.
    pub(super) fn mapped_len(size: usize) -> Option<usize> {
        size.checked_add(HUGE_PAGE - 1).map(|s| s & !(HUGE_PAGE - 1))
    }

    /// A fresh zeroed mapping of `mapped_len(size)` bytes at a 2 MiB boundary, advised for huge
    /// pages; null when the system refuses.
    ///
    /// # Safety
    /// The caller releases it with [`unmap`] and the same `size`.
    pub(super) unsafe fn map(size: usize) -> *mut u8 {
        let Some(len) = mapped_len(size) else { return std::ptr::null_mut() };
        let Some(total) = len.checked_add(HUGE_PAGE) else { return std::ptr::null_mut() };
        // Over-allocate by one huge page, then return the unaligned head and the tail.
        let p = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                total,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            )
        };
        if p == libc::MAP_FAILED {
            return std::ptr::null_mut();
        }
        let start = p as usize;
        let aligned = (start + HUGE_PAGE - 1) & !(HUGE_PAGE - 1);
        let head = aligned - start;
        let tail = total - head - len;
        unsafe {
            if head > 0 {
                libc::munmap(p, head);
            }
            if tail > 0 {
                libc::munmap((aligned + len) as *mut libc::c_void, tail);
            }
            // Advice only: without transparent huge pages the mapping keeps small pages.
            libc::madvise(aligned as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
        }
        aligned as *mut u8
    }

    /// Releases a mapping of [`map`].
    ///
    /// # Safety
    /// `ptr` came from [`map`] (or [`remap`]) with this `size`.
    pub(super) unsafe fn unmap(ptr: *mut u8, size: usize) {
        if let Some(len) = mapped_len(size) {
            unsafe { libc::munmap(ptr as *mut libc::c_void, len) };
        }
    }

    /// Resizes a mapping of [`map`] from `old` to `new` bytes (both at least the threshold),
    /// moving it if needed (page-aligned then, not necessarily 2 MiB-aligned); null on failure,
    /// the old mapping then untouched.
    ///
    /// # Safety
    /// `ptr` came from [`map`] (or [`remap`]) with size `old`.
    pub(super) unsafe fn remap(ptr: *mut u8, old: usize, new: usize) -> *mut u8 {
        let (Some(old_len), Some(new_len)) = (mapped_len(old), mapped_len(new)) else {
            return std::ptr::null_mut();
        };
        if old_len == new_len {
            return ptr;
        }
        let p = unsafe { libc::mremap(ptr as *mut libc::c_void, old_len, new_len, libc::MREMAP_MAYMOVE) };
        if p == libc::MAP_FAILED {
            std::ptr::null_mut()
        } else {
            p as *mut u8
        }
    }
}

#[cfg(target_os = "linux")]
impl HugePageAlloc {
    /// Whether an allocation of this layout is mapped (and so released) by this module.
    fn mapped(layout: &Layout) -> bool {
        layout.size() >= HUGE_THRESHOLD && layout.align() <= HUGE_PAGE
    }
}

#[cfg(target_os = "linux")]
unsafe impl GlobalAlloc for HugePageAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if Self::mapped(&layout) {
            unsafe { imp::map(layout.size()) }
        } else {
            unsafe { System.alloc(layout) }
        }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if Self::mapped(&layout) {
            // Fresh anonymous mappings are zero.
            unsafe { imp::map(layout.size()) }
        } else {
            unsafe { System.alloc_zeroed(layout) }
        }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if Self::mapped(&layout) {
            unsafe { imp::unmap(ptr, layout.size()) }
        } else {
            unsafe { System.dealloc(ptr, layout) }
        }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let Ok(new_layout) = Layout::from_size_align(new_size, layout.align()) else {
            return std::ptr::null_mut();
        };
        match (Self::mapped(&layout), Self::mapped(&new_layout)) {
            // mremap keeps page alignment only.
            (true, true) if layout.align() <= 4096 => unsafe { imp::remap(ptr, layout.size(), new_size) },
            (false, false) => unsafe { System.realloc(ptr, layout, new_size) },
            _ => {
                let new = unsafe { self.alloc(new_layout) };
                if !new.is_null() {
                    unsafe {
                        std::ptr::copy_nonoverlapping(ptr, new, layout.size().min(new_size));
                        self.dealloc(ptr, layout);
                    }
                }
                new
            }
        }
    }
}

#[cfg(not(target_os = "linux"))]
unsafe impl GlobalAlloc for HugePageAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Allocations below and above the threshold, zeroed or not, aligned as asked, grown and
    /// shrunk across the threshold with their contents kept, then released.
    #[test]
    fn allocations_on_both_sides_of_the_threshold_keep_their_contents() {
        let a = HugePageAlloc;
        for &(size, align) in &[(64, 8), (HUGE_THRESHOLD - 8, 16), (HUGE_THRESHOLD, 8), (3 * HUGE_THRESHOLD + 5, 4096)]
        {
            let layout = Layout::from_size_align(size, align).unwrap();
            unsafe {
                let z = a.alloc_zeroed(layout);
                assert!(!z.is_null() && (z as usize).is_multiple_of(align), "size {size}");
                assert!(std::slice::from_raw_parts(z, size).iter().all(|&b| b == 0), "zeroed, size {size}");
                a.dealloc(z, layout);
                let p = a.alloc(layout);
                assert!(!p.is_null() && (p as usize).is_multiple_of(align), "size {size}");
                for i in (0..size).step_by(4093) {
                    *p.add(i) = (i % 251) as u8;
                }
                // Grow past the threshold and beyond the mapping's last huge page, then shrink below.
                let mut cur = (p, layout);
                for new_size in [size + HUGE_THRESHOLD, size / 2 + 1] {
                    let q = a.realloc(cur.0, cur.1, new_size);
                    assert!(!q.is_null() && (q as usize).is_multiple_of(align.min(4096)), "{size} → {new_size}");
                    for i in (0..size.min(new_size)).step_by(4093) {
                        assert_eq!(*q.add(i), (i % 251) as u8, "{size} → {new_size} at {i}");
                    }
                    cur = (q, Layout::from_size_align(new_size, align).unwrap());
                }
                a.dealloc(cur.0, cur.1);
            }
        }
    }
}
