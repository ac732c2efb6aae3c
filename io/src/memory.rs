//! The memory check before a user-sized allocation: an allocation the machine cannot
//! hold is refused with a line saying how much it needs, instead of growing until
//! the kernel's out-of-memory killer ends the process without a word.

/// Bytes of memory available to a new allocation without swapping: `MemAvailable`
/// of `/proc/meminfo` (Linux 3.14+); `None` where it cannot be read.
pub fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_mem_available(&text)
}

fn parse_mem_available(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let mut words = line.split_whitespace().skip(1);
    let kib: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") | None => kib.checked_mul(1024),
        Some(_) => None,
    }
}

/// `bytes` as gigabytes with two decimals (`"1.25 GB"`).
pub fn gigabytes(bytes: u64) -> String {
    format!("{:.2} GB", bytes as f64 / 1e9)
}

/// Refuses `needed` bytes for `what` when they exceed the memory available
/// ([`available_bytes`]), with a message naming both amounts. Where the available
/// memory cannot be read, nothing is refused.
pub fn check(needed: u64, what: &str) -> Result<(), String> {
    check_against(needed, available_bytes(), what)
}

fn check_against(needed: u64, available: Option<u64>, what: &str) -> Result<(), String> {
    match available {
        Some(avail) if needed > avail => Err(format!(
            "{what} needs about {} of memory but {} is available (MemAvailable in /proc/meminfo)",
            gigabytes(needed),
            gigabytes(avail)
        )),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mem_available_is_read_in_bytes_and_a_larger_need_is_refused() {
        let text = "MemTotal: 16000000 kB\nMemFree: 100 kB\nMemAvailable:    2000000 kB\n";
        assert_eq!(parse_mem_available(text), Some(2_048_000_000));
        assert_eq!(parse_mem_available("MemTotal: 1 kB\n"), None);
        let err = check_against(3_000_000_000, Some(2_048_000_000), "--gaussians 9")
            .expect_err("too large");
        assert!(
            err.contains("--gaussians 9 needs about 3.00 GB of memory but 2.05 GB"),
            "{err}"
        );
        check_against(1_000, Some(2_048_000_000), "small").expect("fits");
        check_against(u64::MAX, None, "unknown").expect("no information, no refusal");
    }
}
