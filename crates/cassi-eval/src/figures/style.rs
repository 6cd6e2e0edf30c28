//! Shared look: font sizes, the series palette, marker shapes.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::font::FAMILY;

/// Font sizes (pixels), scaled with the figure so that a large figure keeps
/// readable text and a small one is not swamped by it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Theme {
    pub title: f64,
    pub subtitle: f64,
    pub label: f64,
    pub tick: f64,
    pub legend: f64,
    pub value: f64,
}

impl Theme {
    pub fn for_size(width: u32, height: u32) -> Self {
        // Geometric mean of the two sides against a 1000×650 reference.
        let s = (f64::from(width) * f64::from(height) / 650_000.0)
            .sqrt()
            .clamp(0.8, 2.0);
        Self {
            title: 20.0 * s,
            subtitle: 14.5 * s,
            label: 14.0 * s,
            tick: 12.0 * s,
            legend: 13.0 * s,
            value: 10.0 * s,
        }
    }

    /// A stroke width that grows a little with the figure.
    pub fn stroke(&self) -> u32 {
        (self.tick / 6.0).round().max(2.0) as u32
    }

    /// Marker half-size in pixels.
    pub fn marker(&self) -> i32 {
        (self.tick * 0.42).round().max(3.0) as i32
    }
}

/// A text style of the embedded font, black, anchored at `pos`.
pub(crate) fn text(size: f64, h: HPos, v: VPos) -> TextStyle<'static> {
    TextStyle::from((FAMILY, size).into_font())
        .color(&BLACK)
        .pos(Pos::new(h, v))
}

/// Colour-blind-safe series colours (Okabe & Ito), in the order series are
/// given; the four scenarios Ideal / Assumed / Corrected / Oracle get blue,
/// vermillion, green, purple. Cycles after eight.
const PALETTE: [RGBColor; 8] = [
    RGBColor(0x00, 0x72, 0xB2),
    RGBColor(0xD5, 0x5E, 0x00),
    RGBColor(0x00, 0x9E, 0x73),
    RGBColor(0xCC, 0x79, 0xA7),
    RGBColor(0xE6, 0x9F, 0x00),
    RGBColor(0x56, 0xB4, 0xE9),
    RGBColor(0x88, 0x22, 0x55),
    RGBColor(0x66, 0x66, 0x66),
];

/// The colour of series `i`.
pub(crate) fn series_color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Grid lines.
pub(crate) const GRID: RGBColor = RGBColor(0xDD, 0xDD, 0xDD);
/// Reference lines (y = x).
pub(crate) const REFERENCE: RGBColor = RGBColor(0x80, 0x80, 0x80);

/// Marker shapes, so that series stay distinct in grey-scale print.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Marker {
    Circle,
    Square,
    TriangleUp,
    Diamond,
    TriangleDown,
    Cross,
}

impl Marker {
    /// The marker of series `i`.
    pub fn for_series(i: usize) -> Self {
        const ALL: [Marker; 6] = [
            Marker::Circle,
            Marker::Square,
            Marker::TriangleUp,
            Marker::Diamond,
            Marker::TriangleDown,
            Marker::Cross,
        ];
        ALL[i % ALL.len()]
    }

    /// Draws the marker centred at pixel `(x, y)` of `area` with half-size `r`.
    pub fn draw<DB: DrawingBackend>(
        self,
        area: &DrawingArea<DB, plotters::coord::Shift>,
        (x, y): (i32, i32),
        r: i32,
        color: RGBColor,
    ) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        let fill = color.filled();
        let edge = ShapeStyle::from(&WHITE).stroke_width(1);
        match self {
            Marker::Circle => {
                area.draw(&Circle::new((x, y), r, fill))?;
                area.draw(&Circle::new((x, y), r, edge))
            }
            Marker::Square => {
                let q = r * 9 / 10;
                area.draw(&Rectangle::new([(x - q, y - q), (x + q, y + q)], fill))
            }
            Marker::TriangleUp | Marker::TriangleDown => {
                let s = if self == Marker::TriangleUp { 1 } else { -1 };
                let h = r + r / 4;
                area.draw(&Polygon::new(
                    vec![(x, y - s * h), (x + h, y + s * r), (x - h, y + s * r)],
                    fill,
                ))
            }
            Marker::Diamond => {
                let h = r + r / 4;
                area.draw(&Polygon::new(
                    vec![(x, y - h), (x + h, y), (x, y + h), (x - h, y)],
                    fill,
                ))
            }
            Marker::Cross => {
                let w = (r / 2).max(2);
                let st = color.stroke_width(w as u32);
                area.draw(&PathElement::new(vec![(x - r, y - r), (x + r, y + r)], st))?;
                area.draw(&PathElement::new(vec![(x - r, y + r), (x + r, y - r)], st))
            }
        }
    }
}
