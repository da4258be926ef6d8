//! Inertialization (Bollo 2017, offset form): transitions without pops, decayed by springs.
