//! Binding for the online tracker and the assignment/cost helpers (owned by the assoc work).
//!
//! Inputs may be float32 or float64 arrays; C-contiguous float64 boxes (and float32 embeddings)
//! are read in place, others are converted once. The GIL is released while the tracker runs.

use std::borrow::Cow;

use assoc::{Embeddings, ParamKind, ParamValue, TrackerParams};
use numpy::ndarray::{Array1, Array2};
use numpy::prelude::*;
use numpy::{PyArray1, PyArray2, PyReadonlyArrayDyn, PyUntypedArray};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyTuple};

use crate::errors::{busy_error, input_error, parameter_error, track_error};

/// A float array of either precision, borrowed from Python.
enum FloatArray<'py> {
    F64(PyReadonlyArrayDyn<'py, f64>),
    F32(PyReadonlyArrayDyn<'py, f32>),
}

impl<'py> FloatArray<'py> {
    fn extract(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Self> {
        if let Ok(a) = obj.extract::<PyReadonlyArrayDyn<'py, f64>>() {
            return Ok(Self::F64(a));
        }
        if let Ok(a) = obj.extract::<PyReadonlyArrayDyn<'py, f32>>() {
            return Ok(Self::F32(a));
        }
        match obj.cast::<PyUntypedArray>() {
            Ok(a) => Err(input_error(format!(
                "{name} must be a float32 or float64 array, got dtype {}",
                a.dtype()
            ))),
            Err(_) => Err(input_error(format!(
                "{name} must be a numpy array, got {}",
                obj.get_type().name()?
            ))),
        }
    }

    fn shape(&self) -> &[usize] {
        match self {
            Self::F64(a) => a.shape(),
            Self::F32(a) => a.shape(),
        }
    }

    fn to_f64(&self) -> Cow<'_, [f64]> {
        match self {
            Self::F64(a) => c_order_slice(a).map_or_else(
                || Cow::Owned(a.as_array().iter().copied().collect()),
                Cow::Borrowed,
            ),
            Self::F32(a) => Cow::Owned(a.as_array().iter().map(|&x| f64::from(x)).collect()),
        }
    }

    fn to_f32(&self) -> Cow<'_, [f32]> {
        match self {
            Self::F32(a) => c_order_slice(a).map_or_else(
                || Cow::Owned(a.as_array().iter().copied().collect()),
                Cow::Borrowed,
            ),
            Self::F64(a) => Cow::Owned(a.as_array().iter().map(|&x| x as f32).collect()),
        }
    }
}

/// The array's memory when it is row-major contiguous (`as_slice` alone also accepts Fortran
/// order, whose memory order is not the logical one).
fn c_order_slice<'a, T: numpy::Element>(a: &'a PyReadonlyArrayDyn<'_, T>) -> Option<&'a [T]> {
    if a.is_c_contiguous() {
        a.as_slice().ok()
    } else {
        None
    }
}

fn check_2d(a: &FloatArray<'_>, name: &str, cols: Option<usize>) -> PyResult<(usize, usize)> {
    let shape = a.shape();
    match (shape, cols) {
        ([r, c], Some(want)) if *c == want => Ok((*r, *c)),
        ([r, c], None) => Ok((*r, *c)),
        _ => Err(input_error(format!(
            "{name} must have shape [N, {}], got {shape:?}",
            cols.map_or("D".to_string(), |c| c.to_string())
        ))),
    }
}

pub fn param_value(name: &str, kind: ParamKind, v: &Bound<'_, PyAny>) -> PyResult<ParamValue> {
    let is_bool = v.is_instance_of::<PyBool>() || v.get_type().name()? == "bool_";
    let wrong = |what: &str| parameter_error(format!("{name} must be {what}, got {v}"));
    Ok(match kind {
        ParamKind::Bool if is_bool => ParamValue::Bool(v.extract::<bool>()?),
        ParamKind::Bool => return Err(wrong("a bool")),
        ParamKind::Int if !is_bool => {
            ParamValue::Int(v.extract::<i64>().map_err(|_| wrong("an integer"))?)
        }
        ParamKind::Int => return Err(wrong("an integer")),
        ParamKind::Float if !is_bool => {
            ParamValue::Float(v.extract::<f64>().map_err(|_| wrong("a number"))?)
        }
        ParamKind::Float => return Err(wrong("a number")),
        ParamKind::Choice => ParamValue::Choice(v.extract::<String>().map_err(|_| wrong("a str"))?),
    })
}

/// A parameter value as a Python object.
fn value_object<'py>(py: Python<'py>, v: ParamValue) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        ParamValue::Float(f) => f.into_pyobject(py)?.into_any(),
        ParamValue::Int(i) => i.into_pyobject(py)?.into_any(),
        ParamValue::Bool(b) => PyBool::new(py, b).to_owned().into_any(),
        ParamValue::Choice(s) => s.into_pyobject(py)?.into_any(),
    })
}

/// The keyword arguments that give `TrackerParams::pure()`: those where it differs from the
/// defaults.
fn pure_params(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let (pure, defaults) = (TrackerParams::pure(), TrackerParams::default());
    let d = PyDict::new(py);
    for s in assoc::PARAMS {
        let v = pure.get(s.name).expect("every row has a field");
        if Some(&v) != defaults.get(s.name).as_ref() {
            d.set_item(s.name, value_object(py, v)?)?;
        }
    }
    Ok(d)
}

/// The parameter table as Python data: one dict per parameter with its name, Python type
/// name, default value, range (as text), one-line doc and group (`core` or its block), in the
/// table's order.
fn param_table(py: Python<'_>) -> PyResult<Bound<'_, PyTuple>> {
    let defaults = TrackerParams::default();
    let rows = assoc::PARAMS
        .iter()
        .map(|s| {
            let d = PyDict::new(py);
            d.set_item("name", s.name)?;
            d.set_item("type", s.kind.python_type())?;
            d.set_item(
                "default",
                value_object(py, defaults.get(s.name).expect("row"))?,
            )?;
            d.set_item("range", s.range.describe())?;
            d.set_item("doc", s.doc)?;
            d.set_item("group", assoc::params::group(s.name))?;
            Ok(d)
        })
        .collect::<PyResult<Vec<_>>>()?;
    PyTuple::new(py, rows)
}

/// Online pedestrian tracker: `Tracker(motion="frvo", **params)`.
#[pyclass(module = "densepeds._core", name = "Tracker")]
pub struct PyTracker {
    inner: assoc::Tracker,
}

type UpdateResult<'py> = (
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<i64>>,
);

#[pymethods]
impl PyTracker {
    #[new]
    #[pyo3(signature = (motion = "frvo", **params))]
    fn new(motion: &str, params: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut p = TrackerParams::default();
        p.set("motion", ParamValue::Choice(motion.into()))
            .map_err(track_error)?;
        if let Some(d) = params {
            for (k, v) in d.iter() {
                let name: String = k.extract()?;
                // An unknown name is reported by `set`, with the known ones.
                let kind = TrackerParams::kind_of(&name).unwrap_or(ParamKind::Float);
                p.set(&name, param_value(&name, kind, &v)?)
                    .map_err(track_error)?;
            }
        }
        let inner = assoc::Tracker::new(p).map_err(track_error)?;
        Ok(Self { inner })
    }

    /// One frame: boxes [N, 4] (x1, y1, x2, y2), scores [N], optional embeddings [N, D].
    /// Returns (ids int64 [M], boxes float64 [M, 4], scores float32 [M], det_index int64 [M]).
    #[pyo3(signature = (boxes, scores, embeddings = None))]
    fn update<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
        boxes: &Bound<'py, PyAny>,
        scores: &Bound<'py, PyAny>,
        embeddings: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<UpdateResult<'py>> {
        let boxes = FloatArray::extract(boxes, "boxes")?;
        let (n, _) = check_2d(&boxes, "boxes", Some(4))?;
        let scores = FloatArray::extract(scores, "scores")?;
        if scores.shape() != [n] {
            return Err(input_error(format!(
                "scores must have shape [{n}] (one per box), got {:?}",
                scores.shape()
            )));
        }
        let emb = embeddings
            .map(|e| FloatArray::extract(e, "embeddings"))
            .transpose()?;
        let dim = match &emb {
            Some(e) => {
                let (rows, d) = check_2d(e, "embeddings", None)?;
                if rows != n {
                    return Err(input_error(format!(
                        "embeddings must have one row per box ({n}), got {rows}"
                    )));
                }
                d
            }
            None => 0,
        };
        let box_data = boxes.to_f64();
        let score_data = scores.to_f64();
        let emb_data = emb.as_ref().map(|e| e.to_f32());
        let mut this = slf.try_borrow_mut().map_err(|_| busy_error())?;
        let tracker = &mut this.inner;
        let out = py
            .detach(|| {
                let e = emb_data.as_deref().map(|data| Embeddings { data, dim });
                tracker.update(&box_data, &score_data, e)
            })
            .map_err(track_error)?;
        let m = out.len();
        let ids: Array1<i64> = out.iter().map(|o| o.id as i64).collect();
        let flat: Vec<f64> = out.iter().flat_map(|o| o.bbox).collect();
        let bxs = Array2::from_shape_vec((m, 4), flat).expect("4 values per track");
        let sc: Array1<f32> = out.iter().map(|o| o.score as f32).collect();
        let di: Array1<i64> = out
            .iter()
            .map(|o| o.det_index.map_or(-1, |j| j as i64))
            .collect();
        Ok((
            ids.into_pyarray(py),
            bxs.into_pyarray(py),
            sc.into_pyarray(py),
            di.into_pyarray(py),
        ))
    }

    /// The image size in pixels, for telling a track that left the image from a hidden one.
    fn set_image_size(&mut self, width: f64, height: f64) -> PyResult<()> {
        self.inner
            .set_image_size(width, height)
            .map_err(track_error)
    }

    /// Forgets all tracks; ids restart at 1.
    fn reset(slf: &Bound<'_, Self>) -> PyResult<()> {
        slf.try_borrow_mut()
            .map_err(|_| busy_error())?
            .inner
            .reset();
        Ok(())
    }

    /// Every parameter (including `motion`) with its current value.
    #[getter]
    fn params<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        let py = slf.py();
        let this = slf.try_borrow().map_err(|_| busy_error())?;
        let p = this.inner.params();
        let d = PyDict::new(py);
        for s in assoc::PARAMS {
            d.set_item(
                s.name,
                value_object(py, p.get(s.name).expect("every row has a field"))?,
            )?;
        }
        Ok(d)
    }

    /// Frames processed since creation or the last reset.
    #[getter]
    fn frame_count(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(slf
            .try_borrow()
            .map_err(|_| busy_error())?
            .inner
            .frame_count())
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let this = slf.try_borrow().map_err(|_| busy_error())?;
        Ok(format!(
            "Tracker(motion={:?}, frames={}, tracks={})",
            assoc::params::motion_name(this.inner.params().motion),
            this.inner.frame_count(),
            this.inner.num_tracks()
        ))
    }
}

type IndexPair<'py> = (Bound<'py, PyArray1<i64>>, Bound<'py, PyArray1<i64>>);

/// Like `scipy.optimize.linear_sum_assignment`: (row_ind, col_ind) of a minimum-cost assignment
/// of min(N, M) pairs; `inf` entries are forbidden. InputError when infeasible or NaN.
#[pyfunction]
fn linear_sum_assignment<'py>(
    py: Python<'py>,
    cost: &Bound<'py, PyAny>,
) -> PyResult<IndexPair<'py>> {
    let cost = FloatArray::extract(cost, "cost")?;
    let (n, m) = check_2d(&cost, "cost", None)?;
    let data = cost.to_f64();
    let pairs = py
        .detach(|| assoc::linear_sum_assignment(&data, n, m))
        .map_err(track_error)?;
    let rows: Array1<i64> = pairs.iter().map(|p| p.0 as i64).collect();
    let cols: Array1<i64> = pairs.iter().map(|p| p.1 as i64).collect();
    Ok((rows.into_pyarray(py), cols.into_pyarray(py)))
}

fn boxes_of(a: &FloatArray<'_>, name: &str) -> PyResult<Vec<[f64; 4]>> {
    check_2d(a, name, Some(4))?;
    let flat = a.to_f64();
    assoc::cost::validate_boxes(&flat).map_err(track_error)?;
    Ok(flat
        .chunks_exact(4)
        .map(|b| [b[0], b[1], b[2], b[3]])
        .collect())
}

/// IoU matrix [N, M] between boxes a [N, 4] and b [M, 4] (x1, y1, x2, y2).
#[pyfunction]
fn iou_matrix<'py>(
    py: Python<'py>,
    a: &Bound<'py, PyAny>,
    b: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let a = boxes_of(&FloatArray::extract(a, "a")?, "a")?;
    let b = boxes_of(&FloatArray::extract(b, "b")?, "b")?;
    let m = assoc::cost::iou_matrix(&a, &b);
    Ok(Array2::from_shape_vec((a.len(), b.len()), m)
        .expect("N x M values")
        .into_pyarray(py))
}

/// Cosine distance matrix [N, M], 1 - a.b / (|a| |b|), between rows of a [N, D] and b [M, D].
#[pyfunction]
fn cosine_distance_matrix<'py>(
    py: Python<'py>,
    a: &Bound<'py, PyAny>,
    b: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let a = FloatArray::extract(a, "a")?;
    let b = FloatArray::extract(b, "b")?;
    let (n, d) = check_2d(&a, "a", None)?;
    let (m, _) = check_2d(&b, "b", Some(d))?;
    let (ad, bd) = (a.to_f32(), b.to_f32());
    if ad.iter().chain(bd.iter()).any(|x| !x.is_finite()) {
        return Err(input_error("embeddings must be finite"));
    }
    let out = if d == 0 {
        vec![1.0; n * m]
    } else {
        assoc::cost::cosine_distance_matrix(&ad, &bd, d)
    };
    Ok(Array2::from_shape_vec((n, m), out)
        .expect("N x M values")
        .into_pyarray(py))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyTracker>()?;
    m.add("PARAMS", param_table(m.py())?)?;
    m.add("PURE_PARAMS", pure_params(m.py())?)?;
    m.add(
        "MAX_DETECTIONS_PER_FRAME",
        assoc::cost::MAX_DETECTIONS_PER_FRAME,
    )?;
    m.add_function(wrap_pyfunction!(linear_sum_assignment, m)?)?;
    m.add_function(wrap_pyfunction!(iou_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(cosine_distance_matrix, m)?)?;
    Ok(())
}
