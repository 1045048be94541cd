//! Speed and recall of `s = 1` coding with a 65,536-atom dictionary (guerin2016 section 5.3,
//! issue 15): the exact nearest-atom search, the inverted-list index at several probe counts,
//! and the 4096-atom Gram path on the same 16,384 Grand Canyon patches (the data of the
//! `omp_large` criterion bench).
//!
//! ```text
//! cargo bench -p relief-benches --bench nearest_index [-- LISTS PROBES...]
//! ```
//!
//! Prints one row per search: seconds, microseconds per signal, the recall (fraction of
//! signals given the exact search's atom), the mean ratio of the found `|<d, x>|` to the exact
//! one, and the mean squared residual relative to the exact search's.

#![allow(clippy::print_stdout)]

use relief_sparse_core::nearest::{AtomIndex, AtomIndexSettings, nearest_atom};
use relief_sparse_core::omp::{OmpSettings, batch_omp};
use relief_testdata::timed;

fn main() {
    // `cargo bench` adds `--bench` to the arguments of a harness-free target.
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .map(|a| a.parse().expect("a number"))
        .collect();
    let lists = args.first().copied().unwrap_or(0);
    let probes: Vec<usize> = if args.len() > 1 {
        args[1..].to_vec()
    } else {
        vec![4, 8, 16, 32]
    };
    let one = OmpSettings {
        sparsity: 1,
        tolerance: None,
    };
    let (d4k, x) = relief_benches::large_dictionary_data(4096, 16_384);
    let n = x.nrows() as f64;
    let (_, t4k) = timed(|| batch_omp(d4k.view(), x.view(), &one).expect("omp"));
    let (d, _) = relief_benches::large_dictionary_data(65_536, 16_384);
    let (exact, te) = timed(|| nearest_atom(d.view(), x.view(), &one).expect("exact"));
    let res_exact: f64 = (0..x.nrows())
        .map(|i| f64::from(exact.residual_sq(i)))
        .sum();
    println!(
        "search                      seconds  us/signal  recall  |<d,x>| ratio  residual ratio"
    );
    println!(
        "gram path, 4096 atoms        {t4k:7.3}  {:9.1}",
        1e6 * t4k / n
    );
    println!(
        "exact, 65,536 atoms          {te:7.3}  {:9.1}  1.0000",
        1e6 * te / n
    );
    for &p in &probes {
        let st = AtomIndexSettings {
            lists,
            probes: p,
            ..AtomIndexSettings::default()
        };
        let (index, tb) = timed(|| AtomIndex::build(d.view(), &st).expect("index"));
        let (codes, tc) = timed(|| index.code(x.view(), None).expect("code"));
        let (recall, ratio) = index.recall(d.view(), x.view()).expect("recall");
        let res: f64 = (0..x.nrows())
            .map(|i| f64::from(codes.residual_sq(i)))
            .sum();
        println!(
            "index {} lists {p:>2} probes   {tc:7.3}  {:9.1}  {recall:.4}  {ratio:.5}        {:.4}   (build {tb:.3} s, largest list {})",
            index.lists(),
            1e6 * tc / n,
            res / res_exact,
            index.largest_list(),
        );
    }
}
