//! From user input to the simulated character and its predicted trajectory (THESIS_NOTES §4).
