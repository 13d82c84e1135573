//! Deterministic synthetic scenes (street, large, hard). To be completed: see issue "Foundation".
