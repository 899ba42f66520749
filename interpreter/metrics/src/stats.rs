//! Statistics over runs (placeholder until implemented below).
