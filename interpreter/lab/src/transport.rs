//! A DDS participant on one lab domain (rustdds, pure Rust) with typed writers and
//! readers for the lab's topics, non-blocking `take`/`read` and deadline-bounded waits.
//!
//! Discovery: rustdds speaks SPDP over the default multicast group and, for participants
//! on the same host, unicast to 127.0.0.1. It has no API for initial peers, so the only
//! initial peers accepted are loopback addresses (already covered by same-host discovery);
//! any other peer — e.g. the lab's RTI Cloud Discovery Service — is a typed error rather
//! than being silently ignored. An `interface` restricts multicast and the advertised
//! locators to that local address.
//!
//! Every rustdds failure is returned as a [`LabError`]; nothing here panics. The module
//! knows nothing of ticks, vehicles or the start-up protocol.

use std::{
    cell::Cell,
    net::IpAddr,
    thread,
    time::{Duration, Instant},
};

use rustdds::{
    DataWriterStatus, DomainParticipant, DomainParticipantBuilder, Publisher, QosPolicies, ReadCondition,
    StatusEvented, Subscriber, Topic, TopicKind, no_key, with_key,
};

use crate::{
    error::LabError,
    messages::{KeyedLabMessage, LabMessage, UnkeyedLabMessage},
    topics::{MAX_DOMAIN_ID, TopicDef},
};

/// How often the waits poll their reader or writer, in milliseconds.
const POLL_INTERVAL_MS: u64 = 1;

/// Largest number of samples one `take`/`read` returns.
const MAX_SAMPLES_PER_CALL: usize = 4096;

/// Where and how a participant discovers its peers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DiscoveryConfig {
    /// The DDS domain (the lab: usually 21; the middleware's local domain: 1).
    pub domain_id: u16,
    /// Unicast discovery peers; only loopback addresses are supported (see module docs).
    pub initial_peers: Vec<IpAddr>,
    /// The local interface address to use for multicast and to advertise; all interfaces
    /// when `None`.
    pub interface: Option<IpAddr>,
}

impl DiscoveryConfig {
    /// Same-host only: domain `domain_id`, loopback peer and interface.
    pub fn loopback(domain_id: u16) -> Self {
        let localhost = IpAddr::from([127, 0, 0, 1]);
        DiscoveryConfig {
            domain_id,
            initial_peers: vec![localhost],
            interface: Some(localhost),
        }
    }
}

/// A DDS domain participant with one publisher and one subscriber for the lab's topics.
pub struct LabParticipant {
    participant: DomainParticipant,
    publisher: Publisher,
    subscriber: Subscriber,
}

impl LabParticipant {
    /// Joins the domain of `config`.
    pub fn new(config: &DiscoveryConfig) -> Result<Self, LabError> {
        // Check what rustdds cannot do before touching the network.
        if config.domain_id > MAX_DOMAIN_ID {
            return Err(LabError::DomainOutOfRange {
                domain: config.domain_id,
            });
        }
        if let Some(peer) = config.initial_peers.iter().find(|p| !p.is_loopback()) {
            return Err(LabError::UnsupportedInitialPeer { peer: *peer });
        }

        // Build the participant; same-host loopback discovery covers loopback peers.
        let mut builder = DomainParticipantBuilder::new(config.domain_id).same_host_loopback(true);
        if let Some(interface) = config.interface {
            builder = builder.with_only_networks([interface]);
        }
        let participant = builder
            .build()
            .map_err(|source| create_error("participant", "", source))?;
        let qos = QosPolicies::qos_none();
        let publisher = participant
            .create_publisher(&qos)
            .map_err(|source| create_error("publisher", "", source))?;
        let subscriber = participant
            .create_subscriber(&qos)
            .map_err(|source| create_error("subscriber", "", source))?;
        Ok(LabParticipant {
            participant,
            publisher,
            subscriber,
        })
    }

    /// The DDS domain this participant is on.
    pub fn domain_id(&self) -> u16 {
        self.participant.domain_id()
    }

    /// A writer on a keyed topic (vehicle states, observations, commands, stop requests).
    pub fn keyed_writer<T: KeyedLabMessage>(&self, topic: &TopicDef<T>) -> Result<KeyedWriter<T>, LabError> {
        let dds_topic = self.topic(topic, TopicKind::WithKey)?;
        let inner = self
            .publisher
            .create_datawriter_cdr::<T>(&dds_topic, Some(topic.writer_qos().policies()))
            .map_err(|source| create_error("writer", topic.name(), source))?;
        Ok(KeyedWriter {
            inner,
            topic: topic.name(),
            matched: MatchedReaders::default(),
        })
    }

    /// A reader on a keyed topic.
    pub fn keyed_reader<T: KeyedLabMessage>(&self, topic: &TopicDef<T>) -> Result<KeyedReader<T>, LabError> {
        let dds_topic = self.topic(topic, TopicKind::WithKey)?;
        let inner = self
            .subscriber
            .create_datareader_cdr::<T>(&dds_topic, Some(topic.reader_qos().policies()))
            .map_err(|source| create_error("reader", topic.name(), source))?;
        Ok(KeyedReader {
            inner,
            topic: topic.name(),
        })
    }

    /// A writer on an unkeyed topic (state list, ready status, system trigger).
    pub fn writer<T: UnkeyedLabMessage>(&self, topic: &TopicDef<T>) -> Result<Writer<T>, LabError> {
        let dds_topic = self.topic(topic, TopicKind::NoKey)?;
        let inner = self
            .publisher
            .create_datawriter_no_key_cdr::<T>(&dds_topic, Some(topic.writer_qos().policies()))
            .map_err(|source| create_error("writer", topic.name(), source))?;
        Ok(Writer {
            inner,
            topic: topic.name(),
            matched: MatchedReaders::default(),
        })
    }

    /// A reader on an unkeyed topic.
    pub fn reader<T: UnkeyedLabMessage>(&self, topic: &TopicDef<T>) -> Result<Reader<T>, LabError> {
        let dds_topic = self.topic(topic, TopicKind::NoKey)?;
        let inner = self
            .subscriber
            .create_datareader_no_key_cdr::<T>(&dds_topic, Some(topic.reader_qos().policies()))
            .map_err(|source| create_error("reader", topic.name(), source))?;
        Ok(Reader {
            inner,
            topic: topic.name(),
        })
    }

    /// The DDS topic for `topic` with the lab's registered type name.
    fn topic<T: LabMessage>(&self, topic: &TopicDef<T>, kind: TopicKind) -> Result<Topic, LabError> {
        self.participant
            .create_topic(
                topic.name().to_owned(),
                topic.type_name().to_owned(),
                &QosPolicies::qos_none(),
                kind,
            )
            .map_err(|source| create_error("topic", topic.name(), source))
    }
}

fn create_error(entity: &'static str, topic: &'static str, source: rustdds::dds::CreateError) -> LabError {
    LabError::Create {
        entity,
        topic,
        source,
    }
}

/// Polls `attempt` every [`POLL_INTERVAL_MS`] until it yields `Some` or `timeout` passes.
fn poll_until<R>(
    topic: &'static str,
    timeout: Duration,
    mut attempt: impl FnMut() -> Result<Option<R>, LabError>,
) -> Result<R, LabError> {
    let started = Instant::now();
    loop {
        if let Some(found) = attempt()? {
            return Ok(found);
        }
        let waited = started.elapsed();
        if waited >= timeout {
            return Err(LabError::Timeout {
                topic,
                waited_ms: waited.as_millis(),
            });
        }
        thread::sleep(Duration::from_millis(POLL_INTERVAL_MS).min(timeout - waited));
    }
}

/// `Some(samples)` when there are any.
fn non_empty<T>(samples: Vec<T>) -> Option<Vec<T>> {
    (!samples.is_empty()).then_some(samples)
}

/// The matched-reader count of a writer, kept from its publication-matched events
/// (rustdds' `get_matched_subscriptions` is a panicking placeholder).
#[derive(Default)]
struct MatchedReaders(Cell<i32>);

impl MatchedReaders {
    /// Drains the writer's status events and returns the current count.
    fn update(&self, mut next_status: impl FnMut() -> Option<DataWriterStatus>) -> usize {
        while let Some(status) = next_status() {
            if let DataWriterStatus::PublicationMatched { current, .. } = status {
                self.0.set(current.count());
            }
        }
        usize::try_from(self.0.get()).unwrap_or(0)
    }
}

/// A typed writer on a keyed topic.
pub struct KeyedWriter<T: KeyedLabMessage> {
    inner: with_key::DataWriterCdr<T>,
    topic: &'static str,
    matched: MatchedReaders,
}

impl<T: KeyedLabMessage> KeyedWriter<T> {
    /// Publishes one sample (the instance is the sample's `vehicle_id`).
    pub fn write(&self, sample: T) -> Result<(), LabError> {
        self.inner
            .write(sample, None)
            .map_err(|e| write_error(self.topic, e.forget_data()))
    }

    /// Number of readers currently matched (QoS-compatible and discovered).
    pub fn matched_readers(&self) -> usize {
        self.matched.update(|| self.inner.try_recv_status())
    }

    /// Waits until at least `count` readers are matched.
    pub fn wait_for_readers(&self, count: usize, timeout: Duration) -> Result<(), LabError> {
        poll_until(self.topic, timeout, || {
            Ok((self.matched_readers() >= count).then_some(()))
        })
    }
}

/// A typed writer on an unkeyed topic.
pub struct Writer<T: UnkeyedLabMessage> {
    inner: no_key::DataWriterCdr<T>,
    topic: &'static str,
    matched: MatchedReaders,
}

impl<T: UnkeyedLabMessage> Writer<T> {
    /// Publishes one sample.
    pub fn write(&self, sample: T) -> Result<(), LabError> {
        self.inner
            .write(sample, None)
            .map_err(|e| write_error(self.topic, e.forget_data()))
    }

    /// Waits until every matched reader acknowledged what was written, so that it is not
    /// lost when the participant is dropped right after (rustdds sends asynchronously).
    /// `Ok(false)` when `timeout` passed first; best-effort writers return `Ok(true)` at once.
    pub fn wait_for_acknowledgments(&self, timeout: Duration) -> Result<bool, LabError> {
        self.inner
            .wait_for_acknowledgments(timeout)
            .map_err(|e| write_error(self.topic, e))
    }

    /// Number of readers currently matched (QoS-compatible and discovered).
    pub fn matched_readers(&self) -> usize {
        self.matched.update(|| self.inner.try_recv_status())
    }

    /// Waits until at least `count` readers are matched.
    pub fn wait_for_readers(&self, count: usize, timeout: Duration) -> Result<(), LabError> {
        poll_until(self.topic, timeout, || {
            Ok((self.matched_readers() >= count).then_some(()))
        })
    }
}

fn write_error(topic: &'static str, source: rustdds::dds::WriteError<()>) -> LabError {
    LabError::Write { topic, source }
}

fn read_error(topic: &'static str) -> impl Fn(rustdds::dds::ReadError) -> LabError {
    move |source| LabError::Read { topic, source }
}

/// A typed reader on a keyed topic; dispose notifications are skipped.
pub struct KeyedReader<T: KeyedLabMessage> {
    inner: with_key::DataReaderCdr<T>,
    topic: &'static str,
}

impl<T: KeyedLabMessage> KeyedReader<T> {
    /// Removes and returns every sample in the reader's cache, oldest first per vehicle.
    pub fn take(&mut self) -> Result<Vec<T>, LabError> {
        let samples = self
            .inner
            .take(MAX_SAMPLES_PER_CALL, ReadCondition::any())
            .map_err(read_error(self.topic))?;
        Ok(samples
            .into_iter()
            .filter_map(|s| s.into_value().value())
            .collect())
    }

    /// Returns the samples not read before, leaving them in the cache.
    pub fn read(&mut self) -> Result<Vec<T>, LabError> {
        let samples = self
            .inner
            .read(MAX_SAMPLES_PER_CALL, ReadCondition::not_read())
            .map_err(read_error(self.topic))?;
        Ok(samples
            .iter()
            .filter_map(|s| match s.value() {
                with_key::Sample::Value(v) => Some((*v).clone()),
                with_key::Sample::Dispose(_) => None,
            })
            .collect())
    }

    /// Takes samples, waiting up to `timeout` for at least one.
    pub fn wait_take(&mut self, timeout: Duration) -> Result<Vec<T>, LabError> {
        let topic = self.topic;
        poll_until(topic, timeout, || self.take().map(non_empty))
    }
}

/// A typed reader on an unkeyed topic.
pub struct Reader<T: UnkeyedLabMessage> {
    inner: no_key::DataReaderCdr<T>,
    topic: &'static str,
}

impl<T: UnkeyedLabMessage> Reader<T> {
    /// Removes and returns every sample in the reader's cache, oldest first.
    pub fn take(&mut self) -> Result<Vec<T>, LabError> {
        let samples = self
            .inner
            .take(MAX_SAMPLES_PER_CALL, ReadCondition::any())
            .map_err(read_error(self.topic))?;
        Ok(samples.into_iter().map(|s| s.into_value()).collect())
    }

    /// Returns the samples not read before, leaving them in the cache.
    pub fn read(&mut self) -> Result<Vec<T>, LabError> {
        let samples = self
            .inner
            .read(MAX_SAMPLES_PER_CALL, ReadCondition::not_read())
            .map_err(read_error(self.topic))?;
        Ok(samples.iter().map(|s| (*s.value()).clone()).collect())
    }

    /// Takes samples, waiting up to `timeout` for at least one.
    pub fn wait_take(&mut self, timeout: Duration) -> Result<Vec<T>, LabError> {
        let topic = self.topic;
        poll_until(topic, timeout, || self.take().map(non_empty))
    }
}
