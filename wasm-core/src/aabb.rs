//! Two-level bounding boxes (64 and 16 frames) over the feature matrix for exact pruned search.
