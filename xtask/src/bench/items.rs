//! The dashboard's work items: one row each, with the goal of the issue that asks for it (the
//! "Speed" sections of issues 3 to 7; issue 2 for the foundation rows). To add a row, append a
//! [`WorkItem`] here whose `criterion_id` is the path of your criterion benchmark under
//! `target/criterion/` (`<group>/<function>/<parameter>`), and, when a peer exists, either the
//! peer script in `xtask/peers/` and the key (seconds, `*_s`) it prints, or the criterion id of
//! a Rust peer timed in the same `cargo bench`.

use super::{Goal, Peer, PeerSource, WorkItem};

const fn script(script: &'static str, key: &'static str, label: &'static str) -> Option<Peer> {
    Some(Peer {
        source: PeerSource::Script { script, key },
        label,
    })
}

const SPAMS_OMP: &str = "SPAMS omp float32 (spams-bin, numThreads=2, same patches)";
const SPAMS_OMP_F64: &str = "SPAMS omp float64 (spams-bin, numThreads=2, same patches)";

/// Every dashboard row, in display order.
pub(crate) const WORK_ITEMS: &[WorkItem] = &[
    // Issue 2: foundation (relief-heightfield).
    WorkItem {
        name: "resample 512^2 -> 128^2 (low-pass), grandcanyon",
        criterion_id: "heightfield/resample_down/512",
        peer: script(
            "foundation.py",
            "resize_aa_512_to_128_s",
            "skimage.transform.resize(anti_aliasing=True, order=3)",
        ),
        goal: Goal::RatioAtMost(2.0),
        units: None,
        note: "",
    },
    WorkItem {
        name: "resample 128^2 -> 512^2 (bicubic), grandcanyon",
        criterion_id: "heightfield/resample_up/128",
        peer: script(
            "foundation.py",
            "resize_128_to_512_s",
            "skimage.transform.resize(order=3)",
        ),
        goal: Goal::RatioAtMost(2.0),
        units: None,
        note: "",
    },
    WorkItem {
        name: "void fill 512^2, 4 holes (~7% voids), grandcanyon",
        criterion_id: "heightfield/fill_voids/512",
        peer: script(
            "foundation.py",
            "inpaint_biharmonic_512_s",
            "skimage.restoration.inpaint_biharmonic",
        ),
        goal: Goal::RatioAtMost(1.0),
        units: None,
        note: "",
    },
    WorkItem {
        name: "void fill N47E011 1201^2 (54,278 SRTM voids)",
        criterion_id: "heightfield/fill_voids_srtm/1201",
        peer: None,
        goal: Goal::SecondsAtMost(2.0),
        units: None,
        note: "",
    },
    // Issue 3: sparse-core (guerin2016).
    WorkItem {
        name: "Batch-OMP K=64 N=256 s=1, 65,536 grandcanyon patches, 2 threads",
        criterion_id: "omp/batch_omp_f32/k64_n256_s1",
        peer: script("spams_omp.py", "k64_n256_s1_s", SPAMS_OMP),
        goal: Goal::SpeedupAtLeast(1.5),
        units: Some((65_536.0, "signals")),
        note: "",
    },
    WorkItem {
        name: "Batch-OMP K=64 N=256 s=4, 65,536 grandcanyon patches, 2 threads",
        criterion_id: "omp/batch_omp_f32/k64_n256_s4",
        peer: script("spams_omp.py", "k64_n256_s4_s", SPAMS_OMP),
        goal: Goal::SpeedupAtLeast(1.5),
        units: Some((65_536.0, "signals")),
        note: "",
    },
    WorkItem {
        name: "Batch-OMP K=64 N=256 s=8, 65,536 grandcanyon patches, 2 threads",
        criterion_id: "omp/batch_omp_f32/k64_n256_s8",
        peer: script("spams_omp.py", "k64_n256_s8_s", SPAMS_OMP),
        goal: Goal::SpeedupAtLeast(1.5),
        units: Some((65_536.0, "signals")),
        note: "",
    },
    WorkItem {
        name: "Batch-OMP K=256 N=1024 s=8, 16,384 grandcanyon patches, 2 threads",
        criterion_id: "omp/batch_omp_f32/k256_n1024_s8",
        peer: script("spams_omp.py", "k256_n1024_s8_s", SPAMS_OMP),
        goal: Goal::SpeedupAtLeast(1.5),
        units: Some((16_384.0, "signals")),
        note: "",
    },
    // Issue 15: s = 1 coding with a 65,536-atom dictionary, per signal no slower than the
    // 4096-atom Gram path on the same 16,384 signals (a Rust peer timed in the same run): the
    // default inverted-list index (8 probes; recall printed by the `nearest_index` bench),
    // and the exact search for reference.
    WorkItem {
        name: "s=1 coding K=64 N=65,536 (atom index, 8 probes), 16,384 grandcanyon patches, 2 threads",
        criterion_id: "omp_large/atom_index_code_f32/k64_n65536_s1",
        peer: Some(Peer {
            source: PeerSource::Criterion("omp_large/batch_omp_f32/k64_n4096_s1"),
            label: "Batch-OMP s=1 with N=4096 (the Gram path's cap), same signals",
        }),
        goal: Goal::RatioAtMost(1.0),
        units: Some((16_384.0, "signals")),
        note: "index built once per dictionary: omp_large/atom_index_build_f32/k64_n65536_s1",
    },
    WorkItem {
        name: "s=1 coding K=64 N=65,536 (exact nearest atom), 16,384 grandcanyon patches, 2 threads",
        criterion_id: "omp_large/batch_omp_f32/k64_n65536_s1",
        peer: Some(Peer {
            source: PeerSource::Criterion("omp_large/batch_omp_f32/k64_n4096_s1"),
            label: "Batch-OMP s=1 with N=4096 (the Gram path's cap), same signals",
        }),
        goal: Goal::None,
        units: Some((16_384.0, "signals")),
        note: "the exact search (--index-probes 0), 16x the correlations of N=4096",
    },
    WorkItem {
        name: "Batch-OMP f64 K=64 N=256 s=1, 65,536 grandcanyon patches, 2 threads",
        criterion_id: "omp/batch_omp_f64/k64_n256_s1",
        peer: script("spams_omp.py", "f64_k64_n256_s1_s", SPAMS_OMP_F64),
        goal: Goal::SpeedupAtLeast(1.5),
        units: Some((65_536.0, "signals")),
        note: "",
    },
    WorkItem {
        name: "Batch-OMP f64 K=64 N=256 s=4, 65,536 grandcanyon patches, 2 threads",
        criterion_id: "omp/batch_omp_f64/k64_n256_s4",
        peer: script("spams_omp.py", "f64_k64_n256_s4_s", SPAMS_OMP_F64),
        goal: Goal::SpeedupAtLeast(1.5),
        units: Some((65_536.0, "signals")),
        note: "",
    },
    WorkItem {
        name: "Batch-OMP f64 K=64 N=256 s=8, 65,536 grandcanyon patches, 2 threads",
        criterion_id: "omp/batch_omp_f64/k64_n256_s8",
        peer: script("spams_omp.py", "f64_k64_n256_s8_s", SPAMS_OMP_F64),
        goal: Goal::SpeedupAtLeast(1.5),
        units: Some((65_536.0, "signals")),
        note: "",
    },
    WorkItem {
        name: "Batch-OMP f64 K=256 N=1024 s=8, 16,384 grandcanyon patches, 2 threads",
        criterion_id: "omp/batch_omp_f64/k256_n1024_s8",
        peer: script("spams_omp.py", "f64_k256_n1024_s8_s", SPAMS_OMP_F64),
        goal: Goal::SpeedupAtLeast(1.5),
        units: Some((16_384.0, "signals")),
        note: "",
    },
    WorkItem {
        name: "SCT rasterisation, 8192^2 window at scale 16.1 (grandcanyon, 128 atoms, s=4)",
        criterion_id: "rasterize/sct_window/8192_scale16.1",
        peer: None,
        goal: Goal::SecondsAtMost(2.0),
        units: Some((8192.0 * 8192.0, "cells")),
        note: "",
    },
    WorkItem {
        name: "construction-tree rasterisation (river carve + replace), 8192^2 window at scale 16.1",
        criterion_id: "rasterize/tree_window/8192_scale16.1",
        peer: None,
        goal: Goal::SecondsAtMost(2.0),
        units: Some((8192.0 * 8192.0, "cells")),
        note: "every node stamped (the issue's 2 s goal is for the SCT window above)",
    },
    // Issue 4: dictionary-learning (guerin2016 sections 4.2, 5.2, 5.3).
    WorkItem {
        name: "K-SVD, ~30k alps 16x16 patches, N=256, s=4, 10 iterations, 2 threads",
        criterion_id: "ksvd/ten_iterations/k256_n256_s4",
        peer: script(
            "spams_traindl.py",
            "traindl_3ep_s",
            "SPAMS trainDL, 3 epochs (online, batch 512), same patches, 2 threads",
        ),
        goal: Goal::SecondsAtMost(5.0),
        units: None,
        note: "different algorithms: compare errors too (our RMSE: the crate's bench_ksvd example)",
    },
    WorkItem {
        name: "K-SVD, one iteration (same data)",
        criterion_id: "ksvd/iteration/k256_n256_s4",
        peer: None,
        goal: Goal::None,
        units: None,
        note: "",
    },
    WorkItem {
        name: "x256 amplification 32^2 -> 8192^2, learned N=256, everything included",
        criterion_id: "amplify/learned_n256/x256_32_to_8192",
        peer: None,
        goal: Goal::None,
        units: Some((8192.0 * 8192.0, "output cells")),
        note: "the paper: 30 s learning + 27 s synthesis; the raster in memory, no file",
    },
    WorkItem {
        name: "x256 amplification 32^2 -> 8192^2 written as a DEFLATE GeoTIFF (as the CLI)",
        criterion_id: "amplify/learned_n256/x256_32_to_8192_geotiff",
        peer: None,
        // Issue 15: <= 4 s all-in through the CLI, GeoTIFF written.
        goal: Goal::SecondsAtMost(4.0),
        units: Some((8192.0 * 8192.0, "output cells")),
        note: "streamed in 512-row bands, libdeflate level 1 with the floating-point predictor",
    },
    WorkItem {
        name: "sketch synthesis 64x128 -> 4096x8192, N=64",
        criterion_id: "amplify/sketch_n64/x64_64x128_to_4096x8192",
        peer: None,
        goal: Goal::SecondsAtMost(3.0),
        units: Some((4096.0 * 8192.0, "output cells")),
        note: "the paper: 15.4 s",
    },
    WorkItem {
        name: "x16 amplification 32^2 -> 512^2, learned N=256",
        criterion_id: "amplify/learned_n256/x16_32_to_512",
        peer: None,
        goal: Goal::None,
        units: Some((512.0 * 512.0, "output cells")),
        note: "",
    },
    // Issue 5: wavelet-lod (Perez et al., wavelet detail synthesis).
    WorkItem {
        name: "DWT forward + inverse 4096^2 f32, 6 levels, CDF 5/3",
        criterion_id: "wavelet_lod/dwt_fwd_inv_cdf53/4096",
        peer: script(
            "pywt_dwt.py",
            "dwt_fwd_inv_bior22_4096_s",
            "PyWavelets wavedec2 + waverec2, bior2.2, symmetric",
        ),
        // Issue 16 raised the goal from 5x to 8x.
        goal: Goal::SpeedupAtLeast(8.0),
        units: Some((4096.0 * 4096.0, "cells")),
        note: "same random-walk surface on both sides (target/bench-data/dwt_surface_4096.npy)",
    },
    WorkItem {
        name: "LOD 4096^2 -> 16384^2, LSA 3x3 (analysis + synthesis, 256-row strips), 2 threads",
        criterion_id: "wavelet_lod/lod_lsa3_x4_strips/4096",
        peer: None,
        // Issue 16: <= 4 s and <= 400 MB peak RSS with the spectral model.
        goal: Goal::SecondsAtMost(4.0),
        units: Some((16384.0 * 16384.0, "output cells")),
        note: "peak memory (<= 400 MB) is measured by the lod_big example under /usr/bin/time -v",
    },
    WorkItem {
        name: "LSA 3x3 window 512^2 on demand, 1024^2 terrain refined by 2 levels",
        criterion_id: "wavelet_lod/lsa3_window_x4/512",
        peer: None,
        goal: Goal::None,
        units: Some((512.0 * 512.0, "output cells")),
        note: "",
    },
    WorkItem {
        name: "GSA window 512^2 on demand, 1024^2 terrain refined by 2 levels",
        criterion_id: "wavelet_lod/gsa_window_x4/512",
        peer: None,
        goal: Goal::None,
        units: Some((512.0 * 512.0, "output cells")),
        note: "",
    },
    WorkItem {
        name: "LSA 3x3 analysis (fits) of a 1024^2 terrain",
        criterion_id: "wavelet_lod/lsa3_analysis/1024",
        peer: None,
        goal: Goal::None,
        units: Some((1024.0 * 1024.0, "cells")),
        note: "",
    },
    WorkItem {
        name: "whole refinement 1024^2 -> 4096^2, LSA 3x3",
        criterion_id: "wavelet_lod/refine_lsa3_x4/1024",
        peer: None,
        goal: Goal::None,
        units: Some((4096.0 * 4096.0, "output cells")),
        note: "",
    },
    WorkItem {
        name: "whole refinement 1024^2 -> 4096^2, GSA",
        criterion_id: "wavelet_lod/refine_gsa_x4/1024",
        peer: None,
        goal: Goal::None,
        units: Some((4096.0 * 4096.0, "output cells")),
        note: "",
    },
    // Issue 6: patch-synth (cruz2015).
    WorkItem {
        name: "guided patch synthesis 1024^2 from a 512^2 exemplar (grandcanyon), 2 threads",
        criterion_id: "quilt/relief_patch_synth_1024_from_512_2threads",
        peer: Some(Peer {
            source: PeerSource::Criterion("quilt/texture_synthesis_512_from_512_8bit_2threads"),
            label: "Embark texture-synthesis 0.8, 512^2 output, 2 threads",
        }),
        goal: Goal::SecondsAtMost(4.0),
        units: Some((1024.0 * 1024.0, "cells")),
        note: "peer gets an 8-bit copy of the exemplar (7.3 m steps) and makes a 4x smaller \
               output (at 1024^2 it takes ~150 s, printed once by the bench): ratio is of \
               running time only",
    },
    WorkItem {
        name: "patch search (PCA + kd-tree, section 3.5), L-shaped overlap, 24-NN among 201,601 \
               patches, 2 threads",
        criterion_id: "quilt_search/pca_kdtree/L_knn24",
        peer: Some(Peer {
            source: PeerSource::Criterion("quilt_search/bruteforce/L_full"),
            label: "exhaustive mean-removed SSD over the full L overlap (same index, 2 threads)",
        }),
        goal: Goal::None,
        units: None,
        note: "the bench prints how many of the exhaustive best 24 the fast search returns",
    },
    WorkItem {
        name: "patch search (PCA to 16 dims + kd-tree), L-shaped overlap, 24-NN, 2 threads",
        criterion_id: "quilt_search/pca_kdtree/L_knn24_pca16",
        peer: Some(Peer {
            source: PeerSource::Criterion("quilt_search/bruteforce/L_full"),
            label: "exhaustive mean-removed SSD over the full L overlap (same index, 2 threads)",
        }),
        goal: Goal::None,
        units: None,
        note: "",
    },
    WorkItem {
        name: "patch search (PCA + kd-tree), left overlap, 24-NN, 2 threads",
        criterion_id: "quilt_search/pca_kdtree/left_knn24",
        peer: None,
        goal: Goal::None,
        units: None,
        note: "",
    },
    WorkItem {
        name: "seam: minimum-error boundary cut (DP) through a 64 x 16 real overlap",
        criterion_id: "quilt_seam/dp/64x16",
        peer: Some(Peer {
            source: PeerSource::Criterion("quilt_seam/greedy/64x16"),
            label: "greedy cut (same table)",
        }),
        goal: Goal::None,
        units: None,
        note: "",
    },
    WorkItem {
        name: "seam: minimum-error boundary cut (DP) through a 256 x 64 real overlap",
        criterion_id: "quilt_seam/dp/256x64",
        peer: Some(Peer {
            source: PeerSource::Criterion("quilt_seam/greedy/256x64"),
            label: "greedy cut (same table)",
        }),
        goal: Goal::None,
        units: None,
        note: "",
    },
    // Issue 7: implicit-volume (paris2019/2021).
    WorkItem {
        name: "tree build, karst + sea scene on ~5 km^2 of N57E011, 2 threads",
        criterion_id: "implicit_volume/tree_build_karst_sea_2threads/5km2",
        peer: None,
        goal: Goal::SecondsAtMost(3.0),
        units: None,
        note: "tree memory (<= 10 MB) is printed by the bench",
    },
    WorkItem {
        name: "tree build, default recipe (karst, sea, cliffs, caves, landforms) on a 128^2 \
               grandcanyon crop (>= 50k nodes), 2 threads",
        criterion_id: "implicit_volume/tree_build_recipe_2threads/grandcanyon_128",
        peer: None,
        goal: Goal::SecondsAtMost(3.0),
        units: None,
        note: "issue 19: tree build <= 3 s for >= 150k nodes (178k on 2026-12-05); paper scale \
               (Table 1: 50k-166k nodes in < 7 s); node count printed by the bench",
    },
    WorkItem {
        name: "tree build, default recipe on a 48^2 N57E011 coast crop, 2 threads",
        criterion_id: "implicit_volume/tree_build_recipe_2threads/n57e011_48",
        peer: None,
        goal: Goal::SecondsAtMost(3.0),
        units: None,
        note: "issue 19",
    },
    WorkItem {
        name: "tree build, every feature on a 60 x 40 N57E011 coast crop (10.7 km^2, about 100k \
               nodes), 2 threads",
        criterion_id: "implicit_volume/tree_build_recipe_2threads/n57e011_60x40",
        peer: None,
        goal: Goal::SecondsAtMost(3.0),
        units: None,
        note: "issue 19: the coast scene (>= 50k nodes); its shore cuts stop at a platform just \
               under the sea since 2026-12-05 (150k nodes before); node count printed by the bench",
    },
    WorkItem {
        name: "field evaluation with BVH, 10k points",
        criterion_id: "implicit_volume/field_10k_points/bvh",
        peer: None,
        goal: Goal::None,
        units: Some((10_000.0, "points")),
        note: "",
    },
    WorkItem {
        name: "field evaluation without BVH, 100 points",
        criterion_id: "implicit_volume/field_100_points/no_bvh",
        peer: None,
        goal: Goal::None,
        units: Some((100.0, "points")),
        note: "",
    },
    WorkItem {
        name: "mesh a 256^3 sampling, field evaluation included, 2 threads",
        criterion_id: "implicit_volume/polygonize_2threads/256",
        peer: None,
        goal: Goal::SecondsAtMost(0.5),
        units: None,
        note: "issue 19: mesh 256^3 <= 0.5 s",
    },
    WorkItem {
        name: "simplify the 256^3 mesh (1.94M triangles) to 200k, 2 threads",
        criterion_id: "implicit_volume/simplify_2threads/256_to_200k",
        peer: None,
        goal: Goal::None,
        units: None,
        note: "issue 19: parallel-planned passes (the heap-driven version took 41-153 s on real scenes)",
    },
    WorkItem {
        name: "marching tetrahedra on the precomputed 256^3 grid, 2 threads",
        criterion_id: "implicit_volume/marching_tetrahedra_precomputed_2threads/256",
        peer: script(
            "skimage_mc.py",
            "marching_cubes_256_s",
            "scikit-image marching_cubes (1 thread), same grid",
        ),
        goal: Goal::None,
        units: None,
        note: "",
    },
    // Drainage and erosion (relief-landscape): priority-flood + D8 accumulation of a 4096^2
    // DEM faster than RichDEM and pysheds (each against the same method: pysheds fills and
    // resolves flats, RichDEM fills with epsilon); stream power + diffusion at least 2x faster per
    // step than fastscapelib; hydraulic erosion of 2048^2 with the default preset <= 10 s.
    WorkItem {
        name: "priority-flood fill + flats + D8 area, 4096^2 (grandcanyon mirrored, 30 m)",
        criterion_id: "landscape/fill_d8/4096",
        peer: script(
            "drainage.py",
            "pysheds_fill_d8_4096_s",
            "pysheds fill_depressions + resolve_flats + flowdir + accumulation (same DEM)",
        ),
        goal: Goal::RatioAtMost(1.0),
        units: None,
        note: "",
    },
    // Issue 46: the tiled drainage of `relief tile plan -- flow` (five passes of
    // `flow::tiled`, 64 tiles of 512^2 one after another in one process, plan files
    // excluded) within 1.5x of the single run's time per cell on the same DEM and products.
    WorkItem {
        name: "tiled fill + flats + D8 cells, 4096^2 as 64 tiles of 512^2 (five passes, one process)",
        criterion_id: "landscape/tiled_fill_d8_cells/4096",
        peer: Some(Peer {
            source: PeerSource::Criterion("landscape/single_fill_d8_cells/4096"),
            label: "the single run (route + cells upstream), same DEM, 2 threads",
        }),
        goal: Goal::RatioAtMost(1.5),
        units: Some((4096.0 * 4096.0, "cells")),
        note: "the CLI plan's per-task I/O and peak RSS: docs/SCALING.md (drainage)",
    },
    // Issue 46: every product of `relief flow` (the seven passes: filling, directions, area,
    // then Strahler order, watersheds, HAND and the network across tile edges) within 1.5x
    // of `FlowSettings::run` on the same DEM.
    WorkItem {
        name: "tiled flow, all products, 4096^2 as 64 tiles of 512^2 (seven passes, one process)",
        criterion_id: "landscape/tiled_flow_all/4096",
        peer: Some(Peer {
            source: PeerSource::Criterion("landscape/single_flow_all/4096"),
            label: "the single run (FlowSettings::run: every raster and the network), 2 threads",
        }),
        goal: Goal::RatioAtMost(1.5),
        units: Some((4096.0 * 4096.0, "cells")),
        note: "the CLI plan's per-task I/O and peak RSS: docs/SCALING.md (drainage)",
    },
    WorkItem {
        name: "Priority-Flood+epsilon + D8 area, 4096^2 (RichDEM's own method)",
        criterion_id: "landscape/fill_eps_d8/4096",
        peer: script(
            "drainage.py",
            "richdem_fill_d8_4096_s",
            "RichDEM FillDepressions(epsilon) + FlowAccumulation(D8) (richdem2, same DEM)",
        ),
        goal: Goal::RatioAtMost(1.0),
        units: None,
        note: "",
    },
    WorkItem {
        name: "stream power + diffusion, one step of 1024^2 (K 2e-4, m 0.4, n 1, D 0.01, 2 threads)",
        criterion_id: "landscape/stream_power_step/1024",
        peer: script(
            "stream_power.py",
            "fastscapelib_spl_diffusion_step_1024_s",
            "fastscapelib 0.3 SPLEroder + DiffusionADIEroder + MST sink resolver, per step",
        ),
        goal: Goal::SpeedupAtLeast(2.0),
        units: None,
        note: "",
    },
    WorkItem {
        name: "hydraulic erosion 2048^2, default settings (80 iterations), 2 threads",
        criterion_id: "landscape/hydraulic/2048",
        peer: None,
        goal: Goal::SecondsAtMost(10.0),
        units: None,
        note: "",
    },
];
