//! mimalloc's one setting for a training process. The `maaf` binary allocates through
//! mimalloc (its `#[global_allocator]` is in `src/main.rs`, not in this library, so a
//! program linking `maaf` keeps the allocator it chooses) and calls
//! [`keep_freed_pages`] first; a program of one's own that trains does the same to get
//! the same memory behaviour.
//!
//! A training step allocates and frees tens of megabytes of tensors (activations,
//! cotangents, images). glibc's malloc hands the freed top of the heap back to the
//! kernel and faults it in again on the next step (about 7000 page faults per
//! 50k-Gaussian render), so maaf allocates through mimalloc. mimalloc by default
//! still *purges* freed memory after a delay (gives the pages back with `madvise`;
//! `purge_delay` = 1000 ms in mimalloc v3's `options.c`), and the kernel then zeroes
//! the same pages again when the next steps fault them in: `clear_page_erms` was 13%
//! of a `perf record` of `maaf bench` at 10k Gaussians, and 5% (the data loading)
//! with purging off. With purging off the process keeps its high-water mark of memory
//! mapped and reuses it, which is what a trainer that repeats one step wants.

/// `mi_option_purge_delay` of `mimalloc.h` (v2 and v3: the 16th entry of
/// `mi_option_e`), which the Rust bindings do not name: the delay in milliseconds
/// before freed memory is returned to the OS, -1 for never.
const MI_OPTION_PURGE_DELAY: libmimalloc_sys::mi_option_t = 15;

/// Turns mimalloc's purging of freed memory off (see the module docs); call first in
/// `main` (the `maaf` binary does). Without mimalloc as the global allocator it only
/// sets an option nothing reads. An explicit `MIMALLOC_PURGE_DELAY` in the environment
/// wins.
#[allow(unsafe_code)]
pub fn keep_freed_pages() {
    if std::env::var_os("MIMALLOC_PURGE_DELAY").is_some() {
        return;
    }
    // SAFETY: `mi_option_set` only stores an integer in mimalloc's option table; it
    // is safe to call at any time from any thread.
    unsafe { libmimalloc_sys::mi_option_set(MI_OPTION_PURGE_DELAY, -1) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[allow(unsafe_code)]
    fn purge_delay() -> std::os::raw::c_long {
        // SAFETY: reads one entry of mimalloc's option table.
        unsafe { libmimalloc_sys::mi_option_get(MI_OPTION_PURGE_DELAY) }
    }

    #[test]
    fn option_15_is_the_purge_delay_and_gets_switched_off() {
        if std::env::var_os("MIMALLOC_PURGE_DELAY").is_some() {
            return;
        }
        // mimalloc v3's default purge delay is 1000 ms: this pins the index.
        assert_eq!(
            purge_delay(),
            1000,
            "option {MI_OPTION_PURGE_DELAY} is not purge_delay"
        );
        keep_freed_pages();
        assert_eq!(purge_delay(), -1);
    }
}
