//! Contact sheets: evenly spaced frames of a preview, shrunk and laid out in a grid, so a whole bake
//! reads at a glance (the README shows the default scene's).

use image::{imageops, Rgba, RgbaImage};

/// Frames on a sheet.
pub const THUMBNAILS: usize = 12;
/// Columns of the grid.
pub const COLUMNS: u32 = 4;
/// Width of one thumbnail [px].
pub const THUMB_WIDTH: u32 = 320;
const GAP: u32 = 4;

/// Indices of up to `count` frames out of `frames`, evenly spaced, first and last included.
pub fn picks(frames: usize, count: usize) -> Vec<usize> {
    if frames <= count {
        return (0..frames).collect();
    }
    let mut p: Vec<usize> = (0..count)
        .map(|i| ((i as f64 * (frames - 1) as f64 / (count - 1) as f64).round()) as usize)
        .collect();
    p.dedup();
    p
}

/// A frame shrunk to the thumbnail width.
pub fn thumbnail(image: &RgbaImage) -> RgbaImage {
    let height =
        (image.height() as u64 * THUMB_WIDTH as u64 / image.width().max(1) as u64).max(1) as u32;
    imageops::resize(image, THUMB_WIDTH, height, imageops::FilterType::Triangle)
}

/// Lays out `(frame number, thumbnail)` pairs row by row on a dark background; under each, a bar
/// whose filled length shows where the frame falls in the sequence.
pub fn compose(thumbnails: &[(usize, RgbaImage)]) -> RgbaImage {
    let th = thumbnails.first().map_or(1, |(_, t)| t.height());
    let columns = COLUMNS.min(thumbnails.len().max(1) as u32);
    let rows = (thumbnails.len() as u32).div_ceil(columns).max(1);
    let bar = 4;
    let width = columns * (THUMB_WIDTH + GAP) + GAP;
    let height = rows * (th + bar + 2 * GAP) + GAP;
    let mut sheet = RgbaImage::from_pixel(width, height, Rgba([24, 26, 30, 255]));
    let last = thumbnails.iter().map(|(f, _)| *f).max().unwrap_or(1).max(1);
    for (i, (frame, thumb)) in thumbnails.iter().enumerate() {
        let (col, row) = (i as u32 % columns, i as u32 / columns);
        let x = GAP + col * (THUMB_WIDTH + GAP);
        let y = GAP + row * (th + bar + 2 * GAP);
        imageops::overlay(&mut sheet, thumb, x as i64, y as i64);
        let filled = (THUMB_WIDTH as u64 * *frame as u64 / last as u64) as u32;
        for dx in 0..THUMB_WIDTH {
            let colour = if dx < filled {
                Rgba([230, 160, 60, 255])
            } else {
                Rgba([70, 72, 78, 255])
            };
            for dy in 0..bar {
                sheet.put_pixel(x + dx, y + th + GAP / 2 + dy, colour);
            }
        }
    }
    sheet
}
