//! A method calibrated for a printer: its planes' tone tables passed through the
//! compensation curve of a measured step wedge ([`crate::press::transfer::Transfer`])
//! before halftoning, whole or in bands.

use crate::error::Result;
use crate::method::rows::RowMethod;
use crate::method::Method;
use crate::press::transfer::Transfer;
use crate::raster::{Halftone, PlaneRef, Planes};

/// A method run on planes whose tone tables are first passed through a transfer curve.
pub struct WithTransfer {
    /// The method.
    pub inner: Box<dyn Method>,
    /// The curves (column 0 for grey; one per plane for colour).
    pub transfer: Transfer,
}

impl WithTransfer {
    /// Plane `c`'s tone table passed through the compensation curve.
    fn table(&self, c: usize, tone: &[f32]) -> Vec<f32> {
        self.transfer.compensated_table(c, tone)
    }
}

/// [`WithTransfer`] streamed: the inner method's rows, the compensated tables built once for
/// the page's tone tables (and again only if those change).
struct TransferRows<'a> {
    outer: &'a WithTransfer,
    inner: Box<dyn RowMethod + 'a>,
    /// Per plane: the tone table the compensated one was built from, and the result.
    tables: Vec<(Vec<f32>, Vec<f32>)>,
}

impl RowMethod for TransferRows<'_> {
    fn band_multiple(&self) -> usize {
        self.inner.band_multiple()
    }

    fn state_bytes(&self, width: usize, planes: usize) -> usize {
        self.inner.state_bytes(width, planes)
    }

    fn next_band(&mut self, input: &Planes<'_>) -> Result<Halftone> {
        self.tables.truncate(input.planes.len());
        for (c, p) in input.planes.iter().enumerate() {
            match self.tables.get(c) {
                Some((src, _)) if src.as_slice() == p.tone => {}
                _ => {
                    let entry = (p.tone.to_vec(), self.outer.table(c, p.tone));
                    if c < self.tables.len() {
                        self.tables[c] = entry;
                    } else {
                        self.tables.push(entry);
                    }
                }
            }
        }
        let planes = Planes {
            width: input.width,
            height: input.height,
            planes: input
                .planes
                .iter()
                .zip(&self.tables)
                .map(|(p, t)| PlaneRef {
                    width: p.width,
                    height: p.height,
                    samples: p.samples,
                    tone: &t.1,
                })
                .collect(),
        };
        self.inner.next_band(&planes)
    }
}

impl Method for WithTransfer {
    fn name(&self) -> String {
        format!("{} + transfer", self.inner.name())
    }

    fn output_size(&self, width: usize, height: usize) -> (usize, usize) {
        self.inner.output_size(width, height)
    }

    fn rows(&self) -> Option<Box<dyn RowMethod + '_>> {
        Some(Box::new(TransferRows {
            outer: self,
            inner: self.inner.rows()?,
            tables: Vec::new(),
        }))
    }

    fn halftone(&self, input: &Planes<'_>) -> Result<Halftone> {
        let tables: Vec<Vec<f32>> = input
            .planes
            .iter()
            .enumerate()
            .map(|(c, p)| self.table(c, p.tone))
            .collect();
        let planes = Planes {
            width: input.width,
            height: input.height,
            planes: input
                .planes
                .iter()
                .zip(&tables)
                .map(|(p, t)| PlaneRef {
                    width: p.width,
                    height: p.height,
                    samples: p.samples,
                    tone: t,
                })
                .collect(),
        };
        self.inner.halftone(&planes)
    }
}
