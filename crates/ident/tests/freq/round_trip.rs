//! Round trips: Bode data from known models, fitted back.
