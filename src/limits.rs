//! How much a run may ask of the machine: requests are estimated before anything is allocated
//! for them and refused with a reason (exit 2) instead of aborting on a failed allocation.

/// Physical memory of this machine in bytes (`None` where it cannot be read).
pub fn physical_memory() -> Option<u64> {
    #[cfg(unix)]
    {
        // SAFETY: sysconf reads system constants; no memory is touched.
        let (pages, size) = unsafe {
            (
                libc::sysconf(libc::_SC_PHYS_PAGES),
                libc::sysconf(libc::_SC_PAGESIZE),
            )
        };
        (pages > 0 && size > 0).then(|| pages as u64 * size as u64)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// The most memory one request may take: the machine's physical memory (64 GiB where unknown).
pub fn memory_budget() -> u64 {
    physical_memory().unwrap_or(64 << 30)
}

/// Ok when `bytes` fit in [`memory_budget`]; else the end of a sentence saying why not
/// ("need about 34.4 GB, more than this machine's 25.2 GB of memory").
pub fn fits_in_memory(bytes: u64) -> Result<(), String> {
    let budget = memory_budget();
    if bytes <= budget {
        return Ok(());
    }
    Err(format!(
        "need about {}, more than this machine's {} of memory",
        size(bytes),
        size(budget)
    ))
}

/// A size in the unit that shows it with three significant figures or so: "34.4 GB",
/// "512 MB", "12 kB", "80 bytes".
pub fn size(bytes: u64) -> String {
    let b = bytes as f64;
    for (unit, scale) in [("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)] {
        if b >= scale {
            return format!("{:.1} {unit}", b / scale);
        }
    }
    format!("{bytes} bytes")
}

/// Bytes free to this user on the filesystem that holds `path` (or, when it does not exist yet,
/// its nearest existing ancestor); `None` where it cannot be read.
pub fn free_disk(path: &std::path::Path) -> Option<u64> {
    let absolute = std::path::absolute(path).ok()?;
    let existing = absolute.ancestors().find(|p| p.exists())?;
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let name = std::ffi::CString::new(existing.as_os_str().as_bytes()).ok()?;
        let mut stat: libc::statvfs = unsafe { std::mem::zeroed() };
        // SAFETY: `name` is a NUL-terminated path and `stat` a plain struct statvfs fills in.
        let status = unsafe { libc::statvfs(name.as_ptr(), &mut stat) };
        (status == 0).then(|| stat.f_bavail as u64 * stat.f_frsize as u64)
    }
    #[cfg(not(unix))]
    {
        let _ = existing;
        None
    }
}

/// Ok when `bytes` fit in the free space of the disk that holds `path` (or when that cannot be
/// read); else the end of a sentence saying why not.
pub fn fits_on_disk(bytes: u64, path: &std::path::Path) -> Result<(), String> {
    match free_disk(path) {
        Some(free) if bytes > free => Err(format!(
            "would write about {}, more than the {} free on the disk of {}",
            size(bytes),
            size(free),
            path.display()
        )),
        _ => Ok(()),
    }
}
