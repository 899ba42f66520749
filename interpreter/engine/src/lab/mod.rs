//! The physical fidelity (`driver: cpm-dds`) and its stand-in: the lab driver ([`LabEngine`]),
//! which plays the CPM Lab's high-level controller over the lab's DDS topics, and the lab
//! emulator ([`Emulator`], `cpmx lab emulate`), which plays the lab's middleware and vehicles
//! from a simulated fidelity of the same spec, on simulated or wall-clock time, with faults.
//!
//! What both sides share lives here: how a spec's lab fidelity becomes a DDS discovery
//! configuration, the conversions between the lab's nanosecond stamps and a run's seconds,
//! the lead time the vehicles need, and the stop command (`safe_stop`). The mapping of states
//! between the lab's messages and the planner's bicycle is in `mapping`.
//!
//! The driver: `driver` (the run), `session` (its endpoints and what it waits for),
//! `preflight` (the checks before a run), `irregular` (what a run notices without ending),
//! `safe_stop`. The emulator: `emulator` (serving runs), `stage` (a run's vehicles and
//! lists), `wire` (its endpoints, a restart), `faults` (drawing a run's faults, faulty
//! topics), `lockstep` and `realtime` (its two clocks).
//!
//! This module does not compute metrics and does not write files.

mod driver;
mod emulator;
mod faults;
mod irregular;
mod lockstep;
mod mapping;
mod preflight;
mod realtime;
mod safe_stop;
mod session;
mod stage;
mod wire;

use std::net::IpAddr;
use std::time::Duration;

use cpmx_lab::{DiscoveryConfig, MAX_DOMAIN_ID};
use cpmx_spec::model::LabFidelity;

pub use driver::LabEngine;
pub use emulator::{EmulateError, Emulator, EmulatorClock, EmulatorEvent, RESEND_INTERVAL};
pub use mapping::{lab_state, policy_state};
pub use safe_stop::{STOP_WINDOW, is_stop_command, stop_command};

pub use cpmx_stack::VEHICLE_LEAD_S;

/// Fewer points than this make the lab's middleware warn (§1.5).
pub const MIN_TRAJECTORY_POINTS: usize = 3;

/// The prefix of the planner's ready announcements (`hlc_<vehicle id>`, §1.5).
pub const HLC_SOURCE_PREFIX: &str = "hlc_";

/// The DDS discovery of a lab fidelity, or why rustdds cannot provide it.
///
/// Initial peers are IP addresses, optionally with a port (`host:port`; the port is not
/// used), or `localhost`; the interface is an address or `lo`. rustdds discovers only
/// through multicast and same-host loopback, so every initial peer must be a loopback
/// address (see `docs/lab.md`).
pub fn discovery_config(lab: &LabFidelity) -> Result<DiscoveryConfig, String> {
    let domain_id = u16::try_from(lab.domain)
        .ok()
        .filter(|d| *d <= MAX_DOMAIN_ID)
        .ok_or_else(|| format!("DDS domain {} is out of range (0..={MAX_DOMAIN_ID})", lab.domain))?;
    let initial_peers = lab
        .initial_peers
        .iter()
        .map(|peer| {
            let address = parse_host(peer).ok_or_else(|| {
                format!("initial peer `{peer}` is not an IP address (`host` or `host:port`, or `localhost`)")
            })?;
            if address.is_loopback() {
                Ok(address)
            } else {
                Err(format!(
                    "initial peer `{peer}` is not on this host: rustdds 0.15 discovers only via \
                     multicast and same-host loopback, it cannot contact initial peers"
                ))
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    let interface = match lab.interface.as_deref() {
        None => None,
        Some("lo") => Some(IpAddr::from([127, 0, 0, 1])),
        Some(text) => Some(text.parse::<IpAddr>().map_err(|_| {
            format!("interface `{text}`: give the interface's IP address (of names only `lo` is known)")
        })?),
    };
    Ok(DiscoveryConfig {
        domain_id,
        initial_peers,
        interface,
    })
}

/// `host`, `host:port`, `[v6]:port` or `localhost` as an address.
fn parse_host(text: &str) -> Option<IpAddr> {
    let text = text.trim();
    if let Ok(address) = text.parse::<IpAddr>() {
        return Some(address);
    }
    if let Ok(socket) = text.parse::<std::net::SocketAddr>() {
        return Some(socket.ip());
    }
    let host = text.rsplit_once(':').map_or(text, |(host, _port)| host);
    (host == "localhost").then(|| IpAddr::from([127, 0, 0, 1]))
}

/// The lab's wait budget as a duration (non-finite or huge values wait a day).
pub(crate) fn timeout(lab: &LabFidelity) -> Duration {
    const DAY_S: f64 = 86_400.0;
    Duration::try_from_secs_f64(lab.timeout_s.min(DAY_S)).unwrap_or(Duration::from_secs(86_400))
}

/// A time span in seconds as whole nanoseconds (negative spans are 0).
pub(crate) fn ns_from_s(span_s: f64) -> u64 {
    cpmx_stack::duration_ns(span_s)
}

/// Seconds from `origin_ns` to `stamp_ns` (negative when before).
pub(crate) fn s_since(origin_ns: u64, stamp_ns: u64) -> f64 {
    (i128::from(stamp_ns) - i128::from(origin_ns)) as f64 / 1e9
}

/// The vehicle id of a ready announcement `hlc_<id>`.
pub(crate) fn hlc_vehicle_id(source_id: &str) -> Option<u8> {
    source_id.strip_prefix(HLC_SOURCE_PREFIX)?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use cpmx_spec::model::LabDriver;

    fn lab(peers: &[&str], interface: Option<&str>) -> LabFidelity {
        LabFidelity {
            driver: LabDriver::CpmDds,
            domain: 21,
            vehicle_ids: vec![1, 2],
            initial_peers: peers.iter().map(|p| (*p).to_owned()).collect(),
            interface: interface.map(str::to_owned),
            timeout_s: 30.0,
            preflight: None,
            ips_age_limit_s: None,
            faults: None,
            communication: None,
        }
    }

    #[test]
    fn loopback_peers_and_interfaces_are_accepted() {
        let config = discovery_config(&lab(&["127.0.0.1", "localhost:7400", "[::1]:7400"], Some("lo")))
            .expect("loopback only");
        assert_eq!(config.domain_id, 21);
        assert_eq!(config.initial_peers.len(), 3);
        assert_eq!(config.interface, Some(IpAddr::from([127, 0, 0, 1])));
        assert!(discovery_config(&lab(&[], Some("10.0.0.5"))).is_ok());
    }

    #[test]
    fn remote_peers_and_unknown_names_are_refused_with_a_reason() {
        let remote = discovery_config(&lab(&["192.168.1.249:25598"], None)).unwrap_err();
        assert!(remote.contains("not on this host"), "{remote}");
        let name = discovery_config(&lab(&["lcc.lab"], None)).unwrap_err();
        assert!(name.contains("not an IP address"), "{name}");
        let interface = discovery_config(&lab(&[], Some("eth0"))).unwrap_err();
        assert!(interface.contains("eth0"), "{interface}");
        let mut far = lab(&[], None);
        far.domain = 233;
        assert!(discovery_config(&far).is_err());
    }

    #[test]
    fn stamps_and_seconds_convert_both_ways() {
        let origin_ns = 1_700_000_000_000_000_000;
        let t_ns = origin_ns + ns_from_s(4.9);
        assert_eq!(s_since(origin_ns, t_ns), 4.9);
        assert_eq!(s_since(t_ns, origin_ns), -4.9);
        assert_eq!(ns_from_s(-1.0), 0);
        assert_eq!(s_since(origin_ns, origin_ns - 60_000_000), -0.06);
        assert_eq!(ns_from_s(f64::NAN), 0);
        assert_eq!(hlc_vehicle_id("hlc_7"), Some(7));
        assert_eq!(hlc_vehicle_id("hlc_x"), None);
        assert_eq!(hlc_vehicle_id("timer_1"), None);
    }
}
