//! DDS domain ids for the tests that run nodes on the wire. The integration tests are one
//! process whose tests run in parallel: each such test has a slot of its own, so that no two
//! of them meet on one domain; the process id spreads the slots of processes running at once
//! (another clone's tests) over the ids, apart most of the time.

/// Slots: `live` 0-3, `graph` 4-5, `cyclone` 6-8.
const SLOTS: u32 = 9;

/// The domain id of `slot` for this process: 20-226 (ids up to 232 keep RustDDS's ports
/// below 65 536).
pub fn domain(slot: u32) -> String {
    assert!(slot < SLOTS, "domain slot {slot} of {SLOTS}");
    (20 + (std::process::id() % 23) * SLOTS + slot).to_string()
}
