//! Files parsed once per process: one command reads a spec's map and actors in its checks,
//! in the trainer's setup and in the experiment it runs. A parsed value is kept with the bytes
//! it was parsed from and reused only for the same bytes, so a file that changed between two
//! reads is parsed again.

use std::collections::VecDeque;
use std::sync::Mutex;

/// The last few values parsed from their bytes (and what else the parse depended on, `K`).
pub(crate) struct Memo<K, V> {
    entries: Mutex<VecDeque<(K, V)>>,
}

/// Values kept per memo: a command uses one map and a few actors; more are parsed again.
const KEPT: usize = 4;

impl<K: PartialEq, V: Clone> Memo<K, V> {
    pub(crate) const fn new() -> Self {
        Self {
            entries: Mutex::new(VecDeque::new()),
        }
    }

    /// The value kept for `key`, or what `parse` makes of it (kept when it succeeds).
    pub(crate) fn get_or_parse<E>(&self, key: K, parse: impl FnOnce(&K) -> Result<V, E>) -> Result<V, E> {
        if let Some(value) = self
            .lock()
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, v)| v.clone())
        {
            return Ok(value);
        }
        let value = parse(&key)?;
        let mut entries = self.lock();
        if entries.len() == KEPT {
            entries.pop_front();
        }
        entries.push_back((key, value.clone()));
        Ok(value)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, VecDeque<(K, V)>> {
        // A panic while the lock was held cannot leave an entry half made: keep using it.
        self.entries
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_bytes_are_parsed_once_and_other_bytes_again() {
        let memo: Memo<Vec<u8>, usize> = Memo::new();
        let mut parses = 0;
        let mut parse = |key: &Vec<u8>| -> Result<usize, ()> {
            parses += 1;
            Ok(key.len())
        };
        assert_eq!(memo.get_or_parse(b"ab".to_vec(), &mut parse), Ok(2));
        assert_eq!(memo.get_or_parse(b"ab".to_vec(), &mut parse), Ok(2));
        assert_eq!(memo.get_or_parse(b"abc".to_vec(), &mut parse), Ok(3));
        assert_eq!(parses, 2);
    }

    #[test]
    fn failures_are_not_kept_and_old_values_make_room() {
        let memo: Memo<u32, u32> = Memo::new();
        assert_eq!(memo.get_or_parse(7, |_| Err::<u32, &str>("bad")), Err("bad"));
        assert_eq!(memo.get_or_parse(7, |k| Ok::<_, ()>(*k)), Ok(7));
        for key in 0..KEPT as u32 {
            memo.get_or_parse(100 + key, |k| Ok::<_, ()>(*k)).unwrap();
        }
        // 7 made room for the newer ones: parsed again.
        assert_eq!(memo.get_or_parse(7, |_| Ok::<_, ()>(70)), Ok(70));
    }
}
