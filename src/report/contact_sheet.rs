//! The contact sheet: one picture with a cell per technique, each cell a labelled row of the
//! frame's images (the shaded image and its signed-error map), shrunk by a whole factor so every
//! cell keeps the frame's aspect ratio and each sheet pixel is the mean of whole frame pixels.

use std::path::Path;

use plotters::prelude::*;

use crate::error::{Error, Result};
use crate::plots::{image_error, render};

/// Largest width of one image in the sheet; wider frames are shrunk by the smallest whole factor
/// that fits.
const MAX_IMAGE_W: u32 = 280;
/// Gap between the images of a cell and around cells.
const GAP: u32 = 10;
/// The label band above each cell's images: a title line and a caption line.
const LABEL_H: u32 = 42;
/// The sheet's own title band.
const HEADER_H: u32 = 56;
/// Failed cells' background.
const FAILED_BG: [u8; 3] = [253, 232, 232];

/// One cell of the sheet.
pub struct SheetCell {
    /// First label line, e.g. the technique's name.
    pub title: String,
    /// Second label line, e.g. "12.3 ms · penumbra MAE 0.021".
    pub caption: String,
    /// The frame-sized RGB images shown left to right (all cells should have as many); empty
    /// for a cell that failed.
    pub images: Vec<Vec<[u8; 3]>>,
    /// Why there are no images: drawn in the cell instead.
    pub failure: Option<String>,
}

/// The whole factor a `width`-wide frame is shrunk by.
pub fn shrink_factor(width: u32) -> u32 {
    width.div_ceil(MAX_IMAGE_W).max(1)
}

/// Writes `cells` as a sheet of `columns` cells per row, each showing `images_per_cell` images
/// of a `width × height` frame, under a title band with `title` and `subtitle`.
///
/// Every image must hold `width × height` pixels (otherwise [`Error::Input`]); drawing or
/// saving failures are [`Error::Image`].
pub fn write_contact_sheet(
    path: &Path,
    title: &str,
    subtitle: &str,
    (width, height): (u32, u32),
    images_per_cell: u32,
    columns: u32,
    cells: &[SheetCell],
) -> Result<()> {
    let pixels = width as usize * height as usize;
    if let Some(bad) = cells
        .iter()
        .find(|c| c.images.iter().any(|img| img.len() != pixels))
    {
        return Err(Error::input(
            path.display().to_string(),
            None,
            format!(
                "cell '{}': every image must be the frame's {width}×{height} pixels",
                bad.title
            ),
        ));
    }
    if width == 0 || height == 0 || cells.is_empty() {
        return Err(image_error(
            path,
            "nothing to draw: empty frame or no cells",
        ));
    }
    let s = shrink_factor(width);
    let (iw, ih) = (width / s, height / s);
    let per = images_per_cell.max(1);
    let cell_w = per * iw + (per - 1) * GAP;
    let cell_h = LABEL_H + ih;
    let columns = columns.clamp(1, cells.len() as u32);
    let rows = (cells.len() as u32).div_ceil(columns);
    let size = (
        GAP + columns * (cell_w + GAP),
        HEADER_H + rows * (cell_h + GAP),
    );
    let origin = |k: usize| -> (u32, u32) {
        let (col, row) = (k as u32 % columns, k as u32 / columns);
        (GAP + col * (cell_w + GAP), HEADER_H + row * (cell_h + GAP))
    };

    let prefill = |buf: &mut [u8]| {
        let stride = size.0 as usize * 3;
        let mut put = |x: u32, y: u32, rgb: [u8; 3]| {
            let o = y as usize * stride + x as usize * 3;
            buf[o..o + 3].copy_from_slice(&rgb);
        };
        for (k, cell) in cells.iter().enumerate() {
            let (x0, y0) = origin(k);
            let y0 = y0 + LABEL_H;
            if cell.images.is_empty() {
                for y in 0..ih {
                    for x in 0..cell_w {
                        put(x0 + x, y0 + y, FAILED_BG);
                    }
                }
            }
            for (i, img) in cell.images.iter().take(per as usize).enumerate() {
                let xi = x0 + i as u32 * (iw + GAP);
                for y in 0..ih {
                    for x in 0..iw {
                        put(xi + x, y0 + y, box_mean(img, width, s, x, y));
                    }
                }
            }
        }
    };

    let draw = |root: &DrawingArea<BitMapBackend<'_, plotters::backend::RGBPixel>, _>| {
        let err = |e: DrawingAreaErrorKind<_>| image_error(path, e);
        let font = |size: u32| ("sans-serif", size).into_font().color(&BLACK);
        let grey = |size: u32| ("sans-serif", size).into_font().color(&BLACK.mix(0.65));
        root.draw(&Text::new(title.to_string(), (GAP as i32, 8), font(20)))
            .map_err(err)?;
        root.draw(&Text::new(subtitle.to_string(), (GAP as i32, 33), grey(14)))
            .map_err(err)?;
        for (k, cell) in cells.iter().enumerate() {
            let (x0, y0) = origin(k);
            let (x0, y0) = (x0 as i32, y0 as i32);
            root.draw(&Text::new(cell.title.clone(), (x0, y0 + 3), font(16)))
                .map_err(err)?;
            root.draw(&Text::new(cell.caption.clone(), (x0, y0 + 22), grey(14)))
                .map_err(err)?;
            let top = y0 + LABEL_H as i32;
            // A frame per image, or one around a failed cell's whole area.
            let frames = if cell.images.is_empty() {
                vec![(x0, cell_w as i32)]
            } else {
                (0..per as i32)
                    .map(|i| (x0 + i * (iw + GAP) as i32, iw as i32))
                    .collect()
            };
            for (xi, fw) in frames {
                root.draw(&Rectangle::new(
                    [(xi - 1, top - 1), (xi + fw, top + ih as i32)],
                    BLACK.mix(0.3).stroke_width(1),
                ))
                .map_err(err)?;
            }
            if let Some(why) = &cell.failure {
                // Wrapped to the cell's width at the font's rough average advance.
                let chars = (cell_w as usize / 7).max(20);
                for (n, line) in wrap(&format!("failed: {why}"), chars)
                    .iter()
                    .take((ih as usize / 16).max(1))
                    .enumerate()
                {
                    root.draw(&Text::new(
                        line.clone(),
                        (x0 + 8, top + 8 + 16 * n as i32),
                        font(13),
                    ))
                    .map_err(err)?;
                }
            }
        }
        Ok(())
    };
    render(path, size, prefill, draw)
}

/// The mean colour of the `s × s` frame pixels behind sheet pixel (`x`, `y`).
fn box_mean(img: &[[u8; 3]], width: u32, s: u32, x: u32, y: u32) -> [u8; 3] {
    let mut sum = [0u32; 3];
    for dy in 0..s {
        for dx in 0..s {
            let p = img[((y * s + dy) * width + x * s + dx) as usize];
            for c in 0..3 {
                sum[c] += u32::from(p[c]);
            }
        }
    }
    let n = s * s;
    sum.map(|v| ((v + n / 2) / n) as u8)
}

/// `text` broken at spaces into lines of at most `chars` characters (longer words are cut).
fn wrap(text: &str, chars: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        let mut word: Vec<char> = word.chars().collect();
        while word.len() > chars {
            if !line.is_empty() {
                lines.push(std::mem::take(&mut line));
            }
            lines.push(word.drain(..chars).collect());
        }
        let word: String = word.into_iter().collect();
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > chars {
            lines.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(&word);
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shrinking_keeps_whole_pixels_and_means_them() {
        assert_eq!(shrink_factor(256), 1);
        assert_eq!(shrink_factor(512), 2);
        assert_eq!(shrink_factor(1024), 4);
        let img = vec![[0, 0, 0], [255, 255, 255], [255, 255, 255], [0, 0, 0]];
        assert_eq!(box_mean(&img, 2, 2, 0, 0), [128, 128, 128]);
    }

    #[test]
    fn failure_text_wraps_at_spaces_and_cuts_long_words() {
        assert_eq!(wrap("a bb ccc", 4), vec!["a bb", "ccc"]);
        assert_eq!(wrap("abcdefgh", 3), vec!["abc", "def", "gh"]);
    }

    #[test]
    fn a_sheet_with_a_failed_cell_is_written() {
        let dir = std::env::temp_dir().join(format!("penumbra-sheet-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("sheet.png");
        let img = vec![[200, 100, 50]; 8 * 6];
        let cells = [
            SheetCell {
                title: "ok".into(),
                caption: "1 ms".into(),
                images: vec![img.clone(), img],
                failure: None,
            },
            SheetCell {
                title: "bad".into(),
                caption: String::new(),
                images: Vec::new(),
                failure: Some("kernel 999 is out of range [1, 32]".into()),
            },
        ];
        write_contact_sheet(&path, "t", "s", (8, 6), 2, 2, &cells).expect("write");
        let sheet = image::open(&path).expect("png").to_rgb8();
        // The first cell's first image starts below the header and its label.
        let p = sheet.get_pixel(GAP + 2, HEADER_H + LABEL_H + 2);
        assert_eq!(p.0, [200, 100, 50]);
        let wrong = [vec![[0u8; 3]; 5]];
        let bad = SheetCell {
            title: "short".into(),
            caption: String::new(),
            images: wrong.to_vec(),
            failure: None,
        };
        assert!(write_contact_sheet(&path, "t", "s", (8, 6), 1, 1, &[bad]).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
