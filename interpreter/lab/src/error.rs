//! The crate's one error type: every rustdds failure, encoding problem and timeout as a
//! value. Rendering is the CLI's job.

use std::net::IpAddr;

/// Anything that can go wrong in the lab middleware layer.
#[derive(Debug, thiserror::Error)]
pub enum LabError {
    /// A message could not be serialised to CDR.
    #[error("cannot encode {type_name} as CDR: {reason}")]
    Encode {
        /// The DDS type name.
        type_name: &'static str,
        /// The serializer's message.
        reason: String,
    },
    /// CDR bytes could not be decoded into a message.
    #[error("cannot decode {type_name} from CDR: {reason}")]
    Decode {
        /// The DDS type name.
        type_name: &'static str,
        /// The deserializer's message.
        reason: String,
    },
    /// The DDS domain id gives UDP ports beyond 65535 (RTPS port mapping: domains 0–232).
    #[error("DDS domain {domain} is out of range (0..={max})", max = crate::MAX_DOMAIN_ID)]
    DomainOutOfRange {
        /// The requested domain.
        domain: u16,
    },
    /// rustdds has no initial-peers API; only same-host discovery (127.0.0.1) and the
    /// default SPDP multicast are available.
    #[error(
        "initial peer {peer} is not supported: rustdds discovers only via multicast and \
         same-host loopback (127.0.0.1)"
    )]
    UnsupportedInitialPeer {
        /// The peer that cannot be contacted.
        peer: IpAddr,
    },
    /// Creating a participant, publisher, subscriber, topic, reader or writer failed.
    #[error("cannot create DDS {entity} for `{topic}`")]
    Create {
        /// What was being created ("participant", "writer", ...).
        entity: &'static str,
        /// The topic concerned (empty for participant-wide entities).
        topic: &'static str,
        /// rustdds' error.
        #[source]
        source: rustdds::dds::CreateError,
    },
    /// Writing a sample failed.
    #[error("cannot write to `{topic}`")]
    Write {
        /// The topic written to.
        topic: &'static str,
        /// rustdds' error (the sample itself is dropped).
        #[source]
        source: rustdds::dds::WriteError<()>,
    },
    /// Reading or taking samples failed.
    #[error("cannot read from `{topic}`")]
    Read {
        /// The topic read from.
        topic: &'static str,
        /// rustdds' error.
        #[source]
        source: rustdds::dds::ReadError,
    },
    /// No sample arrived before the deadline.
    #[error("no sample on `{topic}` within {waited_ms} ms")]
    Timeout {
        /// The topic waited on.
        topic: &'static str,
        /// How long was waited, in milliseconds.
        waited_ms: u128,
    },
}
