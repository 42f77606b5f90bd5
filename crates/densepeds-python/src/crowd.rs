//! Binding for stepping a whole crowd with a motion model (owned by the frvo work).
//!
//! `step_crowd` reads four [N, 2] arrays (converted once to contiguous float64), runs one step of
//! the chosen model with the GIL released, and returns new velocities and positions.

use frvo::{make_model, Agent, MotionKind, MotionParams};
use nalgebra::Vector2;
use numpy::ndarray::Array2;
use numpy::{PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// `densepeds.errors.ParameterError` (a ValueError), or ValueError if that cannot be imported.
fn parameter_error(py: Python<'_>, msg: String) -> PyErr {
    match py
        .import("densepeds.errors")
        .and_then(|m| m.getattr("ParameterError"))
        .and_then(|cls| cls.call1((msg.clone(),)))
    {
        Ok(exc) => PyErr::from_value(exc),
        Err(_) => PyValueError::new_err(msg),
    }
}

/// `obj` as a C-contiguous float64 [N, 2] array, or ValueError naming the argument.
fn as_points<'py>(
    py: Python<'py>,
    obj: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<PyReadonlyArray2<'py, f64>> {
    let np = py.import("numpy")?;
    let arr = np
        .call_method1("ascontiguousarray", (obj, "float64"))
        .map_err(|e| PyValueError::new_err(format!("{name} must be a float array [N, 2]: {e}")))?;
    let Ok(arr) = arr.cast_into::<PyArray2<f64>>() else {
        return Err(PyValueError::new_err(format!(
            "{name} must be a 2-D array of shape [N, 2]"
        )));
    };
    if arr.shape()[1] != 2 {
        return Err(PyValueError::new_err(format!(
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
    neighbor_radius: Option<f64>,
    max_neighbors: Option<usize>,
    time_horizon: Option<f64>,
    max_speed: Option<f64>,
    polygon_sides: Option<usize>,
    sf_relaxation_time: Option<f64>,
    sf_strength: Option<f64>,
    sf_range: Option<f64>,
    threads: Option<usize>,
) -> PyResult<(Points<'py>, Points<'py>)> {
    let kind: MotionKind = motion.parse().map_err(|e| parameter_error(py, e))?;
    if !(dt.is_finite() && dt > 0.0) {
        return Err(parameter_error(
            py,
            format!("dt must be finite and > 0, got {dt}"),
        ));
    }
    let d = MotionParams::default();
    let params = MotionParams {
        neighbor_radius: neighbor_radius.unwrap_or(d.neighbor_radius),
        max_neighbors: max_neighbors.unwrap_or(d.max_neighbors),
        time_horizon: time_horizon.unwrap_or(d.time_horizon),
        max_speed: max_speed.unwrap_or(d.max_speed),
        polygon_sides: polygon_sides.unwrap_or(d.polygon_sides),
        sf_relaxation_time: sf_relaxation_time.unwrap_or(d.sf_relaxation_time),
        sf_strength: sf_strength.unwrap_or(d.sf_strength),
        sf_range: sf_range.unwrap_or(d.sf_range),
        threads: threads.unwrap_or(d.threads),
    };
    params.validate().map_err(|e| parameter_error(py, e))?;

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
            return Err(PyValueError::new_err(format!(
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
