//! The process's allocator: the system's, with large blocks backed by 2 MiB pages where Linux
//! allows it.
//!
//! A fit of a 1e6-sample record maps a few hundred MiB of fresh memory (the text read, the
//! columns, the Jacobian of the whole record, simulation buffers): with 4 KiB pages that is some
//! 45 000 page faults, a sizeable part of the run. Linux here backs memory with huge pages only
//! where asked (`transparent_hugepage` set to `madvise`), so every block of at least
//! [`LARGE`] bytes is marked `MADV_HUGEPAGE` before its first use; its pages are then mapped
//! 2 MiB at a time. A hint only: where it is refused, or on another system, nothing changes.

use std::alloc::{GlobalAlloc, Layout, System};

/// Blocks from this size are marked (smaller ones come from the allocator's heap, already
/// mapped).
const LARGE: usize = 4 << 20;

/// [`System`], marking large blocks for huge pages.
pub struct HugeForLarge;

/// The 2 MiB pages inside `[ptr, ptr + size)` marked `MADV_HUGEPAGE`.
fn advise(ptr: *mut u8, size: usize) {
    #[cfg(target_os = "linux")]
    if size >= LARGE && !ptr.is_null() {
        const HUGE: usize = 2 << 20;
        let start = (ptr as usize).next_multiple_of(HUGE);
        let end = (ptr as usize + size) / HUGE * HUGE;
        if end > start {
            // SAFETY: the range lies inside the block just allocated; MADV_HUGEPAGE changes no
            // contents, only how the pages not yet touched will be mapped.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (ptr, size);
}

// SAFETY: every method forwards to `System` with the same arguments; `advise` only adds a hint
// on the block `System` returned.
unsafe impl GlobalAlloc for HugeForLarge {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as `System::alloc`, the caller's contract.
        let p = unsafe { System.alloc(layout) };
        advise(p, layout.size());
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as `System::alloc_zeroed`, the caller's contract.
        let p = unsafe { System.alloc_zeroed(layout) };
        advise(p, layout.size());
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as `System::dealloc`, the caller's contract.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as `System::realloc`, the caller's contract.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if new_size > layout.size() {
            advise(p, new_size);
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Blocks large and small, zeroed or not, grown and shrunk: the contents are the allocator's
    /// (the hint changes none of them).
    #[test]
    fn blocks_keep_their_contents() {
        for n in [10usize, LARGE / 8 - 1, LARGE / 8 + 12_345, 3 * LARGE / 8] {
            let z = vec![0.0f64; n];
            assert!(z.iter().all(|&v| v == 0.0));
            let mut v: Vec<u64> = (0..n as u64).collect();
            v.extend(0..n as u64);
            assert_eq!(v[n - 1], n as u64 - 1);
            assert_eq!(v[2 * n - 1], n as u64 - 1);
            v.truncate(3);
            v.shrink_to_fit();
            assert_eq!(v, [0, 1, 2]);
        }
    }
}
