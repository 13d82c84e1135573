//! splatbridge-raytrace: see ARCHITECTURE.md.
