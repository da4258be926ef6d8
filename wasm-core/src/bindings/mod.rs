//! The only JS-facing module: thin `Raw*` wrappers over the core, one file per class, mirrored
//! file for file by the TypeScript raw layer in `web/src/core/` (whose classes own `free()`).
//! Arrays are exposed as pointers into WASM memory so TS reads them as zero-copy views.
//!
//! Many characters share one database: a [`database::RawDatabase`] holds it (with its search
//! index) behind an `Rc`, and every [`character::RawCharacter`] or [`crowd::RawCrowd`] made from
//! it keeps a reference, so freeing the database object while characters live is safe.

pub mod builder;
pub mod character;
pub mod closed_mesh;
pub mod crowd;
pub mod database;
pub mod ik;
pub mod recording;
pub mod retarget;
pub mod roles;
pub mod search;

use crate::Error;
use std::cell::Cell;
use wasm_bindgen::prelude::*;

fn js_error(e: Error) -> JsError {
    JsError::new(&e.to_string())
}

thread_local! {
    /// Live `Raw*` objects by kind (databases, characters, crowds, retargeters, builders): what a
    /// page can read to see that removing an avatar freed its memory.
    static LIVE: [Cell<i32>; 5] = const { [Cell::new(0), Cell::new(0), Cell::new(0), Cell::new(0), Cell::new(0)] };
}

/// Kinds counted in [`live_objects`].
#[derive(Clone, Copy)]
pub(crate) enum Kind {
    Database = 0,
    Character = 1,
    Crowd = 2,
    Retargeter = 3,
    Builder = 4,
}

/// Counts one live object of `kind` until it drops.
pub(crate) struct LiveToken(Kind);

impl LiveToken {
    pub(crate) fn new(kind: Kind) -> LiveToken {
        LIVE.with(|l| l[kind as usize].set(l[kind as usize].get() + 1));
        LiveToken(kind)
    }
}

impl Drop for LiveToken {
    fn drop(&mut self) {
        LIVE.with(|l| l[self.0 as usize].set(l[self.0 as usize].get() - 1));
    }
}

/// Live objects as JSON: `{"databases": 1, "characters": 2, "crowds": 0, "retargeters": 2, "builders": 0}`.
#[wasm_bindgen]
pub fn live_objects() -> String {
    LIVE.with(|l| {
        format!(
            r#"{{"databases": {}, "characters": {}, "crowds": {}, "retargeters": {}, "builders": {}}}"#,
            l[0].get(),
            l[1].get(),
            l[2].get(),
            l[3].get(),
            l[4].get()
        )
    })
}
