//! Binding for stepping a whole crowd with a motion model (owned by the frvo work).
//!
//! `step_crowd` reads four [N, 2] arrays (converted once to contiguous float64), runs one step of
//! the chosen model with the GIL released, and returns new velocities and positions.

use assoc::{ParamValue, TrackerParams};
use frvo::{make_model, Agent};
use nalgebra::Vector2;
use numpy::ndarray::Array2;
use numpy::{PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::{input_error, parameter_error, track_error};
use crate::tracker::param_value;

/// `obj` as a C-contiguous float64 [N, 2] array (real numbers only), or InputError naming it.
fn as_points<'py>(
    py: Python<'py>,
    obj: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<PyReadonlyArray2<'py, f64>> {
    let np = py.import("numpy")?;
    let arr = np
        .call_method1("asarray", (obj,))
        .map_err(|e| input_error(format!("{name} must be a float array [N, 2]: {e}")))?;
    let dtype_kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if !"biuf".contains(dtype_kind.as_str()) {
        return Err(input_error(format!(
            "{name} must be a real-valued array [N, 2], got dtype {}",
            arr.getattr("dtype")?
        )));
    }
    let arr = np
        .call_method1("ascontiguousarray", (arr, "float64"))
        .map_err(|e| input_error(format!("{name} must be a float array [N, 2]: {e}")))?;
    let Ok(arr) = arr.cast_into::<PyArray2<f64>>() else {
        return Err(input_error(format!(
            "{name} must be a 2-D array of shape [N, 2]"
        )));
    };
    if arr.shape()[1] != 2 {
        return Err(input_error(format!(
            "{name} must have shape [N, 2], got {:?}",
            arr.shape()
        )));
    }
    Ok(arr.readonly())
}

/// A float64 [N, 2] array handed back to Python.
type Points<'py> = Bound<'py, PyArray2<f64>>;

/// One step of a crowd motion model. Returns `(new_velocities, new_positions)`, both float64
/// [N, 2], with `new_positions = positions + dt * new_velocities`.
#[pyfunction]
#[pyo3(signature = (
    positions, velocities, pref_velocities, axes, *, motion = "frvo", dt = 1.0,
    neighbor_radius = None, max_neighbors = None, time_horizon = None, max_speed = None,
    polygon_sides = None, sf_relaxation_time = None, sf_strength = None, sf_range = None,
    threads = None,
))]
#[allow(clippy::too_many_arguments)]
fn step_crowd<'py>(
    py: Python<'py>,
    positions: &Bound<'py, PyAny>,
    velocities: &Bound<'py, PyAny>,
    pref_velocities: &Bound<'py, PyAny>,
    axes: &Bound<'py, PyAny>,
    motion: &str,
    dt: f64,
    neighbor_radius: Option<&Bound<'py, PyAny>>,
    max_neighbors: Option<&Bound<'py, PyAny>>,
    time_horizon: Option<&Bound<'py, PyAny>>,
    max_speed: Option<&Bound<'py, PyAny>>,
    polygon_sides: Option<&Bound<'py, PyAny>>,
    sf_relaxation_time: Option<&Bound<'py, PyAny>>,
    sf_strength: Option<&Bound<'py, PyAny>>,
    sf_range: Option<&Bound<'py, PyAny>>,
    threads: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Points<'py>, Points<'py>)> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(parameter_error(format!(
            "dt must be finite and > 0, got {dt}"
        )));
    }
    // Each value checked against the tracker's parameter table (the same names and ranges).
    let mut p = TrackerParams::default();
    p.set("motion", ParamValue::Choice(motion.into()))
        .map_err(track_error)?;
    for (name, value) in [
        ("neighbor_radius", neighbor_radius),
        ("max_neighbors", max_neighbors),
        ("time_horizon", time_horizon),
        ("max_speed", max_speed),
        ("polygon_sides", polygon_sides),
        ("sf_relaxation_time", sf_relaxation_time),
        ("sf_strength", sf_strength),
        ("sf_range", sf_range),
        ("threads", threads),
    ] {
        if let Some(v) = value {
            let kind = TrackerParams::kind_of(name).expect("a motion parameter");
            p.set(name, param_value(name, kind, v)?)
                .map_err(track_error)?;
        }
    }
    let (kind, params) = (p.motion, p.motion_params);

    let arrays = [
        as_points(py, positions, "positions")?,
        as_points(py, velocities, "velocities")?,
        as_points(py, pref_velocities, "pref_velocities")?,
        as_points(py, axes, "axes")?,
    ];
    let n = arrays[0].shape()[0];
    for (a, name) in arrays
        .iter()
        .zip(["positions", "velocities", "pref_velocities", "axes"])
    {
        if a.shape()[0] != n {
            return Err(input_error(format!(
                "{name} has {} rows but positions has {n}",
                a.shape()[0]
            )));
        }
    }
    let [pos, vel, pref, ax] = arrays.each_ref().map(|a| a.as_array());
    let row = |a: &numpy::ndarray::ArrayView2<f64>, i: usize| Vector2::new(a[[i, 0]], a[[i, 1]]);
    let agents: Vec<Agent> = (0..n)
        .map(|i| {
            Agent::new(
                row(&pos, i),
                row(&vel, i),
                row(&pref, i),
                ax[[i, 0]],
                ax[[i, 1]],
            )
        })
        .collect();

    let mut model = make_model(kind, params);
    let (new_vel, new_pos) = py.detach(|| {
        let v = model.step(&agents, dt);
        let mut new_vel = Array2::<f64>::zeros((n, 2));
        let mut new_pos = Array2::<f64>::zeros((n, 2));
        for (i, (a, v)) in agents.iter().zip(&v).enumerate() {
            let p = a.pos + dt * v;
            new_vel[[i, 0]] = v.x;
            new_vel[[i, 1]] = v.y;
            new_pos[[i, 0]] = p.x;
            new_pos[[i, 1]] = p.y;
        }
        (new_vel, new_pos)
    });
    Ok((
        PyArray2::from_owned_array(py, new_vel),
        PyArray2::from_owned_array(py, new_pos),
    ))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(step_crowd, m)?)?;
    Ok(())
}
