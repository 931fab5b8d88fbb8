//! Counters and histograms in the Prometheus text exposition format
//! (version 0.0.4). Written by hand: the handful of series we expose do not
//! justify a metrics framework and its registry.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// Upper bounds of the latency buckets, in seconds.
const LATENCY: [f64; 12] = [
    0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.5, 2.5,
];
/// Upper bounds of the cut-size buckets, in clusters.
const SIZE: [f64; 9] = [
    1.0, 10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0, 10000.0, 30000.0,
];

#[derive(Debug, Clone, Default)]
struct Histogram {
    buckets: Vec<u64>,
    sum: f64,
    count: u64,
}

impl Histogram {
    fn observe(&mut self, bounds: &[f64], value: f64) {
        if self.buckets.is_empty() {
            self.buckets = vec![0; bounds.len()];
        }
        for (b, bound) in self.buckets.iter_mut().zip(bounds) {
            if value <= *bound {
                *b += 1;
            }
        }
        self.sum += value;
        self.count += 1;
    }

    fn write(&self, out: &mut String, name: &str, labels: &str, bounds: &[f64]) {
        let sep = if labels.is_empty() { "" } else { "," };
        for (b, bound) in self.buckets.iter().zip(bounds) {
            let _ = writeln!(out, "{name}_bucket{{{labels}{sep}le=\"{bound}\"}} {b}");
        }
        let _ = writeln!(
            out,
            "{name}_bucket{{{labels}{sep}le=\"+Inf\"}} {}",
            self.count
        );
        let _ = writeln!(out, "{name}_sum{{{labels}}} {}", self.sum);
        let _ = writeln!(out, "{name}_count{{{labels}}} {}", self.count);
    }
}

#[derive(Default)]
pub struct Metrics {
    /// (route, status) -> requests.
    requests: Mutex<BTreeMap<(String, u16), u64>>,
    /// route -> latency in seconds.
    latency: Mutex<BTreeMap<String, Histogram>>,
    cut_clusters: Mutex<Histogram>,
    cut_triangles: AtomicU64,
    cuts: AtomicU64,
    pub ws_connections: AtomicUsize,
    ws_updates: AtomicU64,
    reloads: AtomicU64,
}

impl Metrics {
    pub fn request(&self, route: &str, status: u16, seconds: f64) {
        *self
            .requests
            .lock()
            .expect("no panic while holding")
            .entry((route.to_owned(), status))
            .or_default() += 1;
        self.latency
            .lock()
            .expect("no panic while holding")
            .entry(route.to_owned())
            .or_default()
            .observe(&LATENCY, seconds);
    }

    pub fn cut(&self, clusters: usize, triangles: u64) {
        self.cut_clusters
            .lock()
            .expect("no panic while holding")
            .observe(&SIZE, clusters as f64);
        self.cut_triangles.fetch_add(triangles, Ordering::Relaxed);
        self.cuts.fetch_add(1, Ordering::Relaxed);
    }

    pub fn ws_update(&self) {
        self.ws_updates.fetch_add(1, Ordering::Relaxed);
    }

    pub fn reloaded(&self) {
        self.reloads.fetch_add(1, Ordering::Relaxed);
    }

    pub fn render(&self) -> String {
        let mut out = String::new();
        out.push_str("# HELP hdlod_http_requests_total HTTP requests by route and status.\n");
        out.push_str("# TYPE hdlod_http_requests_total counter\n");
        for ((route, status), n) in self.requests.lock().expect("no panic while holding").iter() {
            let _ = writeln!(
                out,
                "hdlod_http_requests_total{{route=\"{route}\",status=\"{status}\"}} {n}"
            );
        }
        out.push_str("# HELP hdlod_http_request_duration_seconds Time to answer, by route.\n");
        out.push_str("# TYPE hdlod_http_request_duration_seconds histogram\n");
        for (route, h) in self.latency.lock().expect("no panic while holding").iter() {
            h.write(
                &mut out,
                "hdlod_http_request_duration_seconds",
                &format!("route=\"{route}\""),
                &LATENCY,
            );
        }
        out.push_str("# HELP hdlod_cut_clusters Clusters per cut (HTTP and WebSocket).\n");
        out.push_str("# TYPE hdlod_cut_clusters histogram\n");
        let mut sizes = self
            .cut_clusters
            .lock()
            .expect("no panic while holding")
            .clone();
        if sizes.buckets.is_empty() {
            sizes.buckets = vec![0; SIZE.len()];
        }
        sizes.write(&mut out, "hdlod_cut_clusters", "", &SIZE);
        let counters = [
            (
                "hdlod_cuts_total",
                "Cuts computed.",
                self.cuts.load(Ordering::Relaxed),
            ),
            (
                "hdlod_cut_triangles_total",
                "Triangles in all cuts.",
                self.cut_triangles.load(Ordering::Relaxed),
            ),
            (
                "hdlod_ws_updates_total",
                "WebSocket cut updates sent.",
                self.ws_updates.load(Ordering::Relaxed),
            ),
            (
                "hdlod_reloads_total",
                "Tree reloads (SIGHUP).",
                self.reloads.load(Ordering::Relaxed),
            ),
        ];
        for (name, help, value) in counters {
            let _ = writeln!(
                out,
                "# HELP {name} {help}\n# TYPE {name} counter\n{name} {value}"
            );
        }
        let _ = writeln!(
            out,
            "# HELP hdlod_ws_connections Open WebSocket streams.\n# TYPE hdlod_ws_connections gauge\nhdlod_ws_connections {}",
            self.ws_connections.load(Ordering::Relaxed)
        );
        out
    }
}
