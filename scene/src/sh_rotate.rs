//! Rotation of real SH coefficients (degrees 1–3) with an object, so a moving object's
//! view-dependent colour follows it. To be completed: see issue "Foundation".
