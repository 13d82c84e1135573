//! splatbridge-hybrid: see ARCHITECTURE.md.
