//! The client's side of `fluorite.dask`: the library's passes over the records and its
//! band writer call back into Python, which runs them as Dask tasks.

use std::sync::Mutex;

use fluorite::image::fit::band::{BandOutputs, OutputJob};
use fluorite::image::fit::outputs::BandMapper;
use fluorite::image::fit::records::{ChunkMapper, ChunkResult, RecordKernel};
use pyo3::prelude::*;
use pyo3::types::PyIterator;

impl BandMapper for PythonMapper<'_> {
    fn write_bands(
        &self,
        job: &OutputJob,
        each: &mut dyn FnMut(usize, BandOutputs) -> fluorite::Result<()>,
    ) -> fluorite::Result<bool> {
        let text = serde_json::to_string(job)
            .map_err(|e| fluorite::Error::invalid("job", e.to_string()))?;
        let fail = |e: PyErr| {
            *self.raised.lock().expect("not poisoned") = Some(e);
            fluorite::Error::invalid("map_bands", "raised an exception")
        };
        let bands = Python::attach(|py| -> PyResult<Py<PyAny>> {
            Ok(self
                .call
                .call1(py, (text,))?
                .bind(py)
                .try_iter()?
                .into_any()
                .unbind())
        })
        .map_err(fail)?;
        loop {
            // The GIL is held only to take the next band: the client's own threads
            // (Dask's event loop) need it while this thread encodes the PNGs.
            let next = Python::attach(|py| -> PyResult<Option<(usize, usize, Vec<u8>)>> {
                match bands.bind(py).cast::<PyIterator>()?.clone().next() {
                    None => Ok(None),
                    Some(item) => Ok(Some(item?.extract()?)),
                }
            })
            .map_err(fail)?;
            let Some((y, clamped, png)) = next else {
                return Ok(true);
            };
            each(y, BandOutputs { clamped, png })?;
        }
    }
}

/// The passes over the records run by a Python callable (``fluorite.dask``'s tasks).
pub(super) struct PythonMapper<'a> {
    pub(super) call: Py<PyAny>,
    /// A Python error of the callable, raised again as it was.
    pub(super) raised: &'a Mutex<Option<PyErr>>,
}

impl ChunkMapper for PythonMapper<'_> {
    fn map_chunks(
        &self,
        kernel: &RecordKernel,
        chunks: usize,
    ) -> fluorite::Result<Vec<ChunkResult>> {
        let text = serde_json::to_string(kernel)
            .map_err(|e| fluorite::Error::invalid("kernel", e.to_string()))?;
        let answer = Python::attach(|py| -> PyResult<Vec<String>> {
            self.call.call1(py, (text, chunks))?.extract(py)
        });
        let texts = match answer {
            Ok(texts) => texts,
            Err(e) => {
                *self.raised.lock().expect("not poisoned") = Some(e);
                return Err(fluorite::Error::invalid(
                    "map_chunks",
                    "raised an exception",
                ));
            }
        };
        texts
            .iter()
            .map(|t| {
                serde_json::from_str(t).map_err(|e| {
                    fluorite::Error::invalid(
                        "map_chunks",
                        format!("returned a result that is not run_records' ({e})"),
                    )
                })
            })
            .collect()
    }
}
