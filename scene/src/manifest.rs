//! The `splatbridge-scene/1` JSON manifest and scene loading (PLY or manifest).
//! To be completed: see issue "Foundation".
