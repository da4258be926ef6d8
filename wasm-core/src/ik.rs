//! Analytic two-bone IK and the foot lock built on it (THESIS_NOTES §7).
