//! splatbridge-convert: see ARCHITECTURE.md.
