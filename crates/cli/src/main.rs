//! `relief`: inspect, convert, preview and make terrain rasters (DEMs). The whole command
//! line lives in [`relief_cli::app`].

fn main() -> std::process::ExitCode {
    keep_freed_memory();
    relief_cli::app::main()
}

/// glibc serves every allocation over 32 MiB with its own `mmap` and unmaps it when it is
/// freed, so a command that allocates and frees whole-raster buffers round after round (the
/// landform pass, erosion, flow routing) gets fresh pages from the kernel every time, which
/// the kernel must zero: a quarter of a 4096 x 8192 sketch synthesis was the kernel clearing
/// pages. Serving them from the heap instead (`M_MMAP_MAX` 0) and keeping up to 2 GiB of freed
/// heap for the next buffer (`M_TRIM_THRESHOLD`) made that run 113 -> 84 s and `relief erode`
/// of 2048^2 12.4 -> 10.5 s, with the same output bytes (docs/ARCHITECTURE.md, "Memory
/// allocation"). The workspace's second `#[allow(unsafe_code)]`: two calls of a C function
/// that only sets allocator options, at start-up before any thread exists.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[allow(unsafe_code)]
fn keep_freed_memory() {
    // SAFETY: `mallopt` only changes glibc's allocator parameters; it is called once, before
    // any other thread is started, and its failure (a 0 return) leaves the defaults.
    unsafe {
        libc::mallopt(libc::M_MMAP_MAX, 0);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
    }
}

/// Other platforms keep their allocator's defaults.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn keep_freed_memory() {}
