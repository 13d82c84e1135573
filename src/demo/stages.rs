//! What each stage of the demo cost: wall time and the process's CPU time (user + system,
//! both cores), so a reader can tell a slow stage from a busy machine.

use std::time::Instant;

/// One timed stage.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Stage {
    pub name: String,
    pub wall_seconds: f64,
    /// `None` where the platform does not report process CPU time.
    pub cpu_seconds: Option<f64>,
}

/// The stages run so far, in order.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Stages {
    pub stages: Vec<Stage>,
}

impl Stages {
    /// Run `f` as the stage `name` and record what it cost (also when it fails).
    pub fn time<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        let cpu0 = process_cpu_seconds();
        let t0 = Instant::now();
        let out = f();
        self.stages.push(Stage {
            name: name.to_string(),
            wall_seconds: t0.elapsed().as_secs_f64(),
            cpu_seconds: cpu0.zip(process_cpu_seconds()).map(|(a, b)| b - a),
        });
        out
    }

    pub fn total_wall(&self) -> f64 {
        self.stages.iter().map(|s| s.wall_seconds).sum()
    }

    pub fn total_cpu(&self) -> Option<f64> {
        self.stages.iter().map(|s| s.cpu_seconds).sum()
    }

    /// A markdown table: stage, wall seconds, CPU seconds, and the total.
    pub fn markdown(&self) -> String {
        let cpu = |c: Option<f64>| c.map_or("–".into(), |c| format!("{c:.1}"));
        let mut s = String::from("| stage | wall s | CPU s |\n|---|---|---|\n");
        for st in &self.stages {
            s.push_str(&format!(
                "| {} | {:.1} | {} |\n",
                st.name,
                st.wall_seconds,
                cpu(st.cpu_seconds)
            ));
        }
        s.push_str(&format!(
            "| **total** | **{:.1}** | **{}** |\n",
            self.total_wall(),
            cpu(self.total_cpu())
        ));
        s
    }
}

/// The 1-minute load average (`/proc/loadavg`), to judge how much of the machine a run had.
pub fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// User + system CPU time of this process in seconds (Linux `/proc/self/stat`, proc(5)
/// fields 14 and 15; `None` elsewhere).
pub fn process_cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    // The command name (field 2) may hold spaces: fields are counted after its ')'.
    let f: Vec<&str> = s.rsplit(')').next()?.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    // USER_HZ is 100 on every Linux platform Rust targets.
    Some(ticks / 100.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_are_recorded_in_order_with_their_totals() {
        let mut s = Stages::default();
        let v = s.time("a", || 1 + 1);
        assert_eq!(v, 2);
        s.time("b", || {
            std::thread::sleep(std::time::Duration::from_millis(20))
        });
        assert_eq!(s.stages.len(), 2);
        assert_eq!(s.stages[1].name, "b");
        // Sleeping 20 ms takes at least that long on any clock.
        assert!(s.stages[1].wall_seconds >= 0.02);
        assert!(
            (s.total_wall() - s.stages[0].wall_seconds - s.stages[1].wall_seconds).abs() < 1e-12
        );
        let md = s.markdown();
        assert!(md.starts_with("| stage | wall s | CPU s |"), "{md}");
        assert!(md.contains("| b | "), "{md}");
        assert!(md.contains("**total**"), "{md}");
    }

    #[test]
    #[cfg(target_os = "linux")]
    fn cpu_time_is_reported_and_grows() {
        let a = process_cpu_seconds().unwrap();
        let mut x = 0u64;
        let t0 = Instant::now();
        // Spin for 50 ms of wall time: CPU time cannot go backwards.
        while t0.elapsed().as_millis() < 50 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        assert!(process_cpu_seconds().unwrap() >= a);
    }
}
