//! Critically damped springs parametrized by half-life (Holden, spring-roll-call).
