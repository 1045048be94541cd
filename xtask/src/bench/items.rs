//! The dashboard's work items: one row each. To add a row, append a [`WorkItem`] here whose
//! `criterion_id` is the path of your criterion benchmark under `target/criterion/`
//! (`<group>/<function>/<parameter>`), and, when a peer exists, the peer script in
//! `xtask/peers/` and the key it prints.

use super::{Goal, Peer, WorkItem};

/// Every dashboard row, in display order.
pub(crate) const WORK_ITEMS: &[WorkItem] = &[
    WorkItem {
        name: "resample 512^2 -> 128^2 (low-pass), grandcanyon",
        criterion_id: "heightfield/resample_down/512",
        peer: Some(Peer {
            script: "foundation.py",
            key: "resize_aa_512_to_128",
            label: "skimage.transform.resize(anti_aliasing=True, order=3)",
        }),
        goal: Goal::RatioAtMost(2.0),
    },
    WorkItem {
        name: "resample 128^2 -> 512^2 (bicubic), grandcanyon",
        criterion_id: "heightfield/resample_up/128",
        peer: Some(Peer {
            script: "foundation.py",
            key: "resize_128_to_512",
            label: "skimage.transform.resize(order=3)",
        }),
        goal: Goal::RatioAtMost(2.0),
    },
    WorkItem {
        name: "void fill 512^2, 4 holes (~7% voids), grandcanyon",
        criterion_id: "heightfield/fill_voids/512",
        peer: Some(Peer {
            script: "foundation.py",
            key: "inpaint_biharmonic_512",
            label: "skimage.restoration.inpaint_biharmonic",
        }),
        goal: Goal::RatioAtMost(1.0),
    },
    WorkItem {
        name: "void fill N47E011 1201^2 (54,278 SRTM voids)",
        criterion_id: "heightfield/fill_voids_srtm/1201",
        peer: None,
        goal: Goal::SecondsAtMost(2.0),
    },
];
