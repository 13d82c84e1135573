//! Process memory figures for reports and benchmarks: the peak resident set (`VmHWM`) and the
//! current one (`VmRSS`) from Linux's `/proc/self/status` (proc(5)). Other systems report
//! nothing (`None`), never a guess.

/// A `kB` field of `/proc/self/status`, in bytes.
pub fn proc_status_bytes(field: &str) -> Option<u64> {
    kb_field("/proc/self/status", field)
}

/// Physical memory (`MemTotal` of `/proc/meminfo`), in bytes.
pub fn physical_bytes() -> Option<u64> {
    kb_field("/proc/meminfo", "MemTotal:")
}

/// The `field  N kB` line of a proc(5) file, in bytes.
fn kb_field(file: &str, field: &str) -> Option<u64> {
    kb_in(&std::fs::read_to_string(file).ok()?, field)
}

/// The `field  N kB` line of a proc(5) file's text, in bytes.
fn kb_in(s: &str, field: &str) -> Option<u64> {
    let line = s.lines().find(|l| l.starts_with(field))?;
    let kb: u64 = line[field.len()..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb * 1024)
}

/// The process's peak resident memory so far, in bytes.
pub fn peak_bytes() -> Option<u64> {
    proc_status_bytes("VmHWM:")
}

/// The process's resident memory now, in bytes.
pub fn resident_bytes() -> Option<u64> {
    proc_status_bytes("VmRSS:")
}

#[cfg(test)]
mod tests {
    /// The peak is at least the current resident size, and both exist on Linux. Both are
    /// read from one snapshot of the file: the kernel reports `VmHWM` as at least `VmRSS` within
    /// a snapshot, but its high-water mark lags, so a peak read after a resident size (other
    /// tests' threads allocating and freeing between the reads) can be below it.
    #[test]
    #[cfg(target_os = "linux")]
    fn peak_covers_resident() {
        let s = std::fs::read_to_string("/proc/self/status").unwrap();
        let rss = super::kb_in(&s, "VmRSS:").unwrap();
        let peak = super::kb_in(&s, "VmHWM:").unwrap();
        assert!(rss > 0 && peak >= rss, "{rss} {peak}");
        assert!(super::resident_bytes().is_some() && super::peak_bytes().is_some());
        assert!(super::physical_bytes().unwrap() > peak);
    }
}
