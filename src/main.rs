//! The `survey` binary: a thin shell over `survey_cli`.
fn main() -> std::process::ExitCode {
    keep_freed_memory();
    survey_cli::main()
}

/// Keep the memory a command frees for its next allocation.
///
/// glibc's allocator maps every block above its mmap threshold (128 KiB at
/// first, raised to the size of a freed block up to 32 MiB) on its own and
/// unmaps it when it is freed, and trims the heap's top beyond twice that
/// threshold: the processing of a survey makes and drops vectors of a value
/// a sample (14 MiB each at 1.8 M samples), and each was mapped and faulted
/// in again page by page. On the 2-core VM of `docs/performance.md` those
/// faults were a fifth of `survey process`'s CPU time; with blocks up to 32
/// MiB taken from the heap and up to 256 MiB free at its top kept, about a
/// quarter of them remain and the command takes about a tenth less CPU.
/// Only the peak is kept: a freed block serves the next one. Not glibc: the
/// allocator's own policy stands.
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // Both are glibc's maxima-in-kind: the largest fixed mmap threshold
        // (`DEFAULT_MMAP_THRESHOLD_MAX` on 64 bits) and a quarter GiB.
        const MMAP_THRESHOLD: libc::c_int = 32 << 20;
        const TRIM_THRESHOLD: libc::c_int = 256 << 20;
        // SAFETY: `mallopt` changes two parameters of the allocator and
        // touches no memory of ours; it is called before any thread starts.
        // A parameter it refuses (returning 0) leaves glibc's default.
        #[allow(unsafe_code)]
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
            libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD);
        }
    }
}
