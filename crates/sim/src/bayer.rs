//! A colour sensor's Bayer filter: each pixel records one colour through
//! an RGGB mosaic, and the other two are interpolated from its neighbours
//! (bilinear demosaicing). A thin red line then shows in the red channel
//! only on every other row and column, and its interpolated shape zips
//! between them: what a stripe detector on a real colour camera sees.

use image::RgbImage;

/// Which colour the RGGB mosaic records at pixel (x, y): 0 red, 1 green, 2 blue.
fn recorded_channel(x: usize, y: usize) -> usize {
    match (x % 2, y % 2) {
        (0, 0) => 0,
        (1, 1) => 2,
        _ => 1,
    }
}

/// `i + offset` mirrored into `0..n` about the border pixels (-1 -> 1,
/// n -> n - 2), which keeps the mosaic's parity; `n` is at least 2.
fn mirrored(i: usize, offset: isize, n: usize) -> usize {
    let j = i as isize + offset;
    let last = n as isize - 1;
    let j = if j < 0 {
        -j
    } else if j > last {
        2 * last - j
    } else {
        j
    };
    j.clamp(0, last) as usize
}

/// Keeps, at every pixel of `image`, the colour an RGGB Bayer filter
/// records there and replaces the other two by the mean of the nearest
/// pixels that record them (the two or four neighbours across, along, or
/// diagonal to it): bilinear demosaicing. Images narrower or lower than
/// two pixels are left as they are.
pub(crate) fn mosaic_and_demosaic(image: &mut RgbImage) {
    let (width, height) = (image.width() as usize, image.height() as usize);
    if width < 2 || height < 2 {
        return;
    }
    let raw: Vec<u8> = (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| image.get_pixel(x as u32, y as u32)[recorded_channel(x, y)])
        .collect();
    let at = |x: usize, y: usize, dx: isize, dy: isize| -> u32 {
        u32::from(raw[mirrored(y, dy, height) * width + mirrored(x, dx, width)])
    };
    let mean = |values: &[u32]| -> u8 {
        let sum: u32 = values.iter().sum();
        let n = values.len() as u32;
        ((sum + n / 2) / n) as u8
    };
    for y in 0..height {
        for x in 0..width {
            let across = [at(x, y, -1, 0), at(x, y, 1, 0)];
            let along = [at(x, y, 0, -1), at(x, y, 0, 1)];
            let plus = [across[0], across[1], along[0], along[1]];
            let diagonal = [at(x, y, -1, -1), at(x, y, 1, -1), at(x, y, -1, 1), at(x, y, 1, 1)];
            let own = raw[y * width + x];
            let rgb = match (x % 2, y % 2) {
                // Red: green on the plus, blue on the diagonals.
                (0, 0) => [own, mean(&plus), mean(&diagonal)],
                // Blue: green on the plus, red on the diagonals.
                (1, 1) => [mean(&diagonal), mean(&plus), own],
                // Green in a red row: red across, blue along.
                (1, 0) => [mean(&across), own, mean(&along)],
                // Green in a blue row: red along, blue across.
                _ => [mean(&along), own, mean(&across)],
            };
            image.put_pixel(x as u32, y as u32, image::Rgb(rgb));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flat_colour_stays_flat() {
        let mut image = RgbImage::from_pixel(6, 5, image::Rgb([200, 90, 30]));
        mosaic_and_demosaic(&mut image);
        assert!(image.pixels().all(|p| p.0 == [200, 90, 30]));
    }

    #[test]
    fn a_one_pixel_red_line_shows_in_red_on_every_row_and_spreads() {
        // A vertical red line one pixel wide at x = 2 (a red column of the
        // mosaic on even rows, a green one on odd rows).
        let mut image = RgbImage::from_pixel(8, 6, image::Rgb([10, 10, 10]));
        for y in 0..6 {
            image.put_pixel(2, y, image::Rgb([250, 10, 10]));
        }
        mosaic_and_demosaic(&mut image);
        for y in 0..6u32 {
            let red: Vec<u8> = (0..8).map(|x| image.get_pixel(x, y)[0]).collect();
            // The peak stays at x = 2 and its neighbours take a share.
            let peak = (0..8).max_by_key(|&x| red[x]).unwrap();
            assert_eq!(peak, 2, "row {y}: {red:?}");
            assert!(red[1] > 10 && red[3] > 10, "row {y}: {red:?}");
        }
        // Odd rows saw the line in no red pixel: their red is interpolated
        // from the rows above and below.
        assert_eq!(image.get_pixel(2, 1)[0], 250);
    }

    #[test]
    fn the_border_mirrors_the_mosaic() {
        assert_eq!(mirrored(0, -1, 5), 1);
        assert_eq!(mirrored(4, 1, 5), 3);
        assert_eq!(mirrored(2, 1, 5), 3);
    }
}
