//! Prints the georeference and summary of a raster (debug helper).
#![allow(clippy::print_stdout)]
fn main() {
    for a in std::env::args().skip(1) {
        match relief_io::read(std::path::Path::new(&a), &relief_io::ReadOptions::default()) {
            Ok(r) => println!(
                "{a}: {:?} {} {}x{} cell {:?} nodata {:?} flipped {} voids {}\n  {:?}",
                r.format,
                r.dtype,
                r.heightfield.width(),
                r.heightfield.height(),
                r.heightfield.cell_size(),
                r.nodata,
                r.rows_flipped,
                r.heightfield.void_count(),
                r.heightfield.georef()
            ),
            Err(e) => println!("{a}: error: {e}"),
        }
    }
}
