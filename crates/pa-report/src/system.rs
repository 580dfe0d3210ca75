//! Probes of the machine a benchmark runs on (Linux `/proc`; elsewhere they report nothing):
//! this process's memory, the load average, the CPU model and the usable cores. The parsing
//! is split from the reading so that it can be tested on fixed text.

/// A memory figure of this process from /proc/self/status in MiB (Linux): `VmHWM` (peak
/// resident set) or `VmRSS` (current).
pub fn status_mib(field: &str) -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    parse_status_mib(&status, field)
}

/// The figure `field` (in kB) of a /proc/self/status text, in MiB.
pub fn parse_status_mib(status: &str, field: &str) -> Option<f64> {
    let line = status.lines().find(|l| l.starts_with(field))?;
    let kb: f64 = line[field.len()..]
        .trim_start_matches(':')
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb / 1024.0)
}

/// Resets VmHWM to the current resident set (Linux 4.0+); false where that is not possible.
pub fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// The 1-minute load average (Linux), to tell a quiet machine from a busy one.
pub fn load_average() -> Option<f64> {
    parse_load_average(&std::fs::read_to_string("/proc/loadavg").ok()?)
}

/// The first figure (1-minute load average) of a /proc/loadavg text.
pub fn parse_load_average(loadavg: &str) -> Option<f64> {
    loadavg.split_whitespace().next()?.parse().ok()
}

/// The CPU model and the number of cores this process may use.
pub fn cpu_description() -> (String, usize) {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| parse_cpu_model(&s))
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    (model, cores)
}

/// The first `model name` of a /proc/cpuinfo text.
pub fn parse_cpu_model(cpuinfo: &str) -> Option<String> {
    cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map(|(_, v)| v.trim().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_figures_in_mib() {
        let status = "Name:\tpropsalive\nVmHWM:\t  204800 kB\nVmRSS:\t   10240 kB\n";
        assert_eq!(parse_status_mib(status, "VmHWM"), Some(200.0));
        assert_eq!(parse_status_mib(status, "VmRSS"), Some(10.0));
        assert_eq!(parse_status_mib(status, "VmSwap"), None);
        assert_eq!(parse_status_mib("VmRSS:\tlots kB\n", "VmRSS"), None);
    }

    #[test]
    fn load_average_is_the_first_figure() {
        assert_eq!(
            parse_load_average("0.52 0.58 0.59 1/467 12345\n"),
            Some(0.52)
        );
        assert_eq!(parse_load_average(""), None);
        assert_eq!(parse_load_average("busy"), None);
    }

    #[test]
    fn cpu_model_is_the_first_model_name() {
        let info = "processor\t: 0\nmodel name\t: Example CPU @ 3.00GHz\n\nprocessor\t: 1\nmodel name\t: Other\n";
        assert_eq!(
            parse_cpu_model(info).as_deref(),
            Some("Example CPU @ 3.00GHz")
        );
        assert_eq!(parse_cpu_model("processor\t: 0\n"), None);
    }

    #[test]
    fn live_probes_do_not_panic() {
        let (model, cores) = cpu_description();
        assert!(!model.is_empty());
        assert!(cores >= 1);
        if cfg!(target_os = "linux") {
            assert!(status_mib("VmRSS").is_some_and(|m| m > 0.0));
            assert!(load_average().is_some());
        }
    }
}
