//! Messages name the flags a user typed and the sizes they get, not library internals
//! (issue 45, "found on the way").

use crate::common::*;

#[test]
fn messages_name_flags_and_what_is_written() {
    let (tmp, input, hf) = tmp_with_crop("in.tif", (0, 0, 64, 48));
    let t = tmp.path();
    // A command a plan cannot split is refused naming the ones it can.
    fails_with(
        &relief![
            "tile",
            "plan",
            t.join("p"),
            "--",
            "synthesize",
            &input,
            t.join("o.tif")
        ],
        &["cannot be planned as tiles", "amplify, refine or"],
        &[],
    );
    // analyze --local names the flag, not the library's field.
    let e = fails_with(
        &relief!["analyze", &input, "--local", "4"],
        &["--local"],
        &[],
    );
    assert!(!e.contains("`window`"), "{e}");
    // learn prints its fit as a fit, not as an error line.
    let out = relief_ok!["learn", &input, t.join("l.dict"), "--atoms", "16"];
    assert!(out.lines().all(|l| !l.starts_with("error:")), "{out}");
    assert!(out.contains("fit:"), "{out}");
    // 16-bit-heightmap flags on a GeoTIFF are said to be ignored, not silently dropped.
    let tif = t.join("c.tif");
    let o = relief_loud(&[
        os("convert"),
        os(&input),
        os(&tif),
        os("--height-range"),
        os("0,5000"),
    ]);
    ok(&o);
    assert_stderr_has(&o, "--height-range applies to 16-bit heightmaps");
    // --size-plus-one reports the size written.
    let png = t.join("c.png");
    let o = relief_loud(&[os("convert"), os(&input), os(&png), os("--size-plus-one")]);
    ok(&o);
    assert_stderr_has(&o, &format!("({} x {})", hf.width() + 1, hf.height() + 1));
    // An exemplar with voids: the command's --fill-voids fills its input, not the exemplar.
    let mut holed = hf.clone();
    holed.as_mut_slice()[100] = f32::NAN;
    let ex = write(t, "holed.tif", &holed);
    fails_with(
        &relief![
            "amplify",
            &input,
            t.join("a.tif"),
            "--exemplar",
            &ex,
            "--fill-voids",
            "--factor",
            "4"
        ],
        &["as exemplar", "relief convert --fill-voids"],
        &[&t.join("a.tif")],
    );
}
