//! Work handed from the threads that compute to threads that wait: finished runs and figures
//! go through a short queue to writer threads of their own, so that each file's wait for the
//! disk (`fsync`) overlaps the computing of the next one and the other writers' waits (the
//! file system commits concurrent `fsync`s together).

use std::sync::Mutex;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

/// Runs `produce` on the calling thread while `threads` threads of their own apply `consume`
/// to each item it sends; returns what `produce` returned and what `consume` gave for the
/// items, in the order they were consumed. At most `2 × threads` items wait in the queue (a
/// full queue holds `produce` up). Every item sent is consumed before this returns, whatever
/// `produce` does after sending it; a panic in `consume` reaches the caller.
pub fn pipelined<I: Send, O: Send, R>(
    threads: usize,
    consume: impl Fn(I) -> O + Sync,
    produce: impl FnOnce(&SyncSender<I>) -> R,
) -> (R, Vec<O>) {
    let threads = threads.max(1);
    let (sender, receiver) = sync_channel::<I>(2 * threads);
    let receiver = Mutex::new(receiver);
    std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| scope.spawn(|| drain(&receiver, &consume)))
            .collect();
        let produced = produce(&sender);
        drop(sender);
        let mut consumed = Vec::new();
        for worker in workers {
            consumed.extend(
                worker
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
            );
        }
        (produced, consumed)
    })
}

/// One writer thread: takes items until the queue is closed and empty.
fn drain<I, O>(receiver: &Mutex<Receiver<I>>, consume: &impl Fn(I) -> O) -> Vec<O> {
    let mut consumed = Vec::new();
    loop {
        // The lock is held only while taking an item, not while consuming it.
        let item = match receiver.lock() {
            Ok(receiver) => receiver.recv(),
            Err(poisoned) => poisoned.into_inner().recv(),
        };
        match item {
            Ok(item) => consumed.push(consume(item)),
            Err(_) => return consumed,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    #[test]
    fn every_item_sent_is_consumed_once_before_it_returns() {
        let consumed_count = AtomicUsize::new(0);
        let (sent, mut consumed) = pipelined(
            3,
            |item: u32| {
                consumed_count.fetch_add(1, Ordering::SeqCst);
                item * 2
            },
            |send| {
                for item in 0..100 {
                    send.send(item).unwrap();
                }
                100
            },
        );
        consumed.sort_unstable();
        assert_eq!(sent, 100);
        assert_eq!(consumed, (0..100).map(|i| i * 2).collect::<Vec<_>>());
        assert_eq!(consumed_count.load(Ordering::SeqCst), 100);
    }

    #[test]
    fn a_full_queue_holds_the_producer_up() {
        // One writer, held at its first item until released: items 1 and 2 fill the queue of
        // 2, so item 3 cannot go in before the writer is released.
        let release = std::sync::Barrier::new(2);
        let (_, consumed) = pipelined(
            1,
            |item: usize| {
                if item == 0 {
                    release.wait();
                }
                item
            },
            |send| {
                for item in 0..3 {
                    send.send(item).unwrap();
                }
                assert!(matches!(
                    send.try_send(3),
                    Err(std::sync::mpsc::TrySendError::Full(3))
                ));
                release.wait();
                for item in 3..10 {
                    send.send(item).unwrap();
                }
            },
        );
        assert_eq!(consumed, (0..10).collect::<Vec<_>>());
    }

    #[test]
    #[should_panic(expected = "consumer failed")]
    fn a_panic_of_a_consumer_reaches_the_caller() {
        pipelined(
            2,
            |item: u8| {
                if item == 3 {
                    panic!("consumer failed");
                }
            },
            |send| {
                for item in 0..5 {
                    let _ = send.send(item);
                }
            },
        );
    }
}
