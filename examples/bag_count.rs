//! Reads one bag with the project's reader and prints, as JSON, every message it recovers
//! (topic, log time, FNV-1a digest of the data), the errors it met, and its recovery summary.
//! Used by `bench/recovery/compare.py` to compare recovery with the Python `mcap` readers.
//!
//! `cargo run --example bag_count -- damaged.mcap`

use chronotope::bag::BagReader;

fn fnv1a(data: &[u8]) -> u64 {
    data.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: bag_count <bag.mcap>");
        std::process::exit(2);
    };
    let mut reader = match BagReader::open(&path) {
        Ok(r) => r,
        Err(e) => {
            println!(
                "{}",
                serde_json::json!({ "open_error": e.to_string(), "messages": [] })
            );
            return;
        }
    };
    let mut messages = Vec::new();
    let mut errors = Vec::new();
    for item in reader.by_ref() {
        match item {
            Ok(m) => messages.push(serde_json::json!([
                m.topic,
                m.log_time_ns,
                format!("{:016x}", fnv1a(&m.data))
            ])),
            Err(e) => errors.push(e.to_string()),
        }
    }
    println!(
        "{}",
        serde_json::json!({
            "messages": messages,
            "errors": errors,
            "recovery": reader.recovery(),
        })
    );
}
