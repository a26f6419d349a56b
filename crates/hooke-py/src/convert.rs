//! Between Python values and hooke's: numpy arrays of vectors and indices, and Python dicts of
//! scene settings, which become the same TOML tables a scene file holds (so they are checked by
//! the same code, with the same messages).

use glam::DVec3;
use numpy::{PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict};

use crate::errors::input;

/// `value` as a numpy array whose dtype kind is one of `kinds` (numpy's letters: `f` float,
/// `i` signed, `u` unsigned), with shape `(N, columns)`. `what` names it in errors.
fn checked_array<'py>(
    value: &Bound<'py, PyAny>,
    what: &str,
    kinds: &str,
    columns: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let numpy = value.py().import("numpy")?;
    let array = numpy.call_method1("asarray", (value,))?;
    let kind: String = array.getattr("dtype")?.getattr("kind")?.extract()?;
    let dtype = array.getattr("dtype")?.str()?.to_string();
    if !kinds.contains(kind.as_str()) {
        return Err(input(format!(
            "{what} must be {} numbers, found dtype {dtype}",
            if kinds == "iu" { "integer" } else { "real" }
        )));
    }
    let shape: Vec<usize> = array.getattr("shape")?.extract()?;
    if shape.len() != 2 || shape[1] != columns {
        return Err(input(format!(
            "{what} must have shape (N, {columns}), found {shape:?}"
        )));
    }
    Ok(array)
}

/// An `(N, K)` array of finite real numbers as rows (read in place when it is contiguous
/// float64).
fn real_rows<const K: usize>(value: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f64; K]>> {
    let array = checked_array(value, what, "fiu", K)?;
    let numpy = value.py().import("numpy")?;
    let array: PyReadonlyArray2<'_, f64> = numpy
        .call_method1("ascontiguousarray", (array, "float64"))?
        .extract()?;
    let rows: Vec<[f64; K]> = array
        .as_array()
        .rows()
        .into_iter()
        .map(|r| std::array::from_fn(|k| r[k]))
        .collect();
    if let Some(i) = rows.iter().position(|r| !r.iter().all(|x| x.is_finite())) {
        return Err(input(format!("{what}: row {i} is not finite")));
    }
    Ok(rows)
}

/// An `(N, 3)` array of real numbers as vectors.
pub fn vectors(value: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<DVec3>> {
    Ok(real_rows::<3>(value, what)?
        .into_iter()
        .map(DVec3::from_array)
        .collect())
}

/// An `(N, 2)` array of texture coordinates, one per vertex of `vertex_count`.
pub fn uvs(value: &Bound<'_, PyAny>, vertex_count: usize) -> PyResult<Vec<[f64; 2]>> {
    let uvs = real_rows::<2>(value, "uvs")?;
    if uvs.len() != vertex_count {
        return Err(input(format!(
            "uvs must have one row per vertex ({vertex_count}), found {}",
            uvs.len()
        )));
    }
    Ok(uvs)
}

/// A `(T, 3)` array of vertex indices as triangles.
pub fn triangles(value: &Bound<'_, PyAny>) -> PyResult<Vec<[u32; 3]>> {
    let what = "triangles";
    let array = checked_array(value, what, "iu", 3)?;
    let size: usize = array.getattr("size")?.extract()?;
    if size > 0 {
        let low: i128 = array.call_method0("min")?.extract()?;
        let high: i128 = array.call_method0("max")?.extract()?;
        if low < 0 || high >= i128::from(u32::MAX) {
            return Err(input(format!(
                "{what}: vertex indices must be 0..{}, found {low}..={high}",
                u32::MAX
            )));
        }
    }
    let numpy = value.py().import("numpy")?;
    let array: PyReadonlyArray2<'_, u32> = numpy
        .call_method1("ascontiguousarray", (array, "uint32"))?
        .extract()?;
    Ok(array
        .as_array()
        .rows()
        .into_iter()
        .map(|r| [r[0], r[1], r[2]])
        .collect())
}

/// A number, or a 1-D array of `len` positive reals (per spring or per vertex).
pub enum PerItem {
    One(f64),
    Each(Vec<f64>),
}

/// `value` as [`PerItem`]: a number, or an array of `len` positive finite reals.
pub fn per_item(value: &Bound<'_, PyAny>, len: usize, what: &str) -> PyResult<PerItem> {
    if let Ok(number) = value.extract::<f64>() {
        return Ok(PerItem::One(number));
    }
    let numpy = value.py().import("numpy")?;
    let array = numpy.call_method1("asarray", (value, "float64"))?;
    let values: Vec<f64> = array.call_method0("ravel")?.extract()?;
    let shape: Vec<usize> = array.getattr("shape")?.extract()?;
    if shape != [len] {
        return Err(input(format!(
            "{what} must be a number or an array of shape ({len},), found shape {shape:?}"
        )));
    }
    if let Some(i) = values.iter().position(|v| !(*v > 0.0 && v.is_finite())) {
        return Err(input(format!(
            "{what}[{i}] must be a positive number, found {}",
            values[i]
        )));
    }
    Ok(PerItem::Each(values))
}

/// Rows as a `(len, K)` numpy array; the vector is handed over, not copied again.
pub fn rows<'py, T: numpy::Element + Copy, const K: usize>(
    py: Python<'py>,
    rows: &[[T; K]],
) -> Bound<'py, PyArray2<T>> {
    let flat: Vec<T> = rows.iter().flatten().copied().collect();
    numpy::ndarray::Array2::from_shape_vec((rows.len(), K), flat).map_or_else(
        |_| unreachable_shape(py),
        |a| numpy::IntoPyArray::into_pyarray(a, py),
    )
}

/// Vectors as a float32 `(N, 3)` array (the solvers' precision).
pub fn positions_f32<'py>(py: Python<'py>, vectors: &[DVec3]) -> Bound<'py, PyArray2<f32>> {
    let flat: Vec<f32> = vectors
        .iter()
        .flat_map(|v| v.as_vec3().to_array())
        .collect();
    numpy::ndarray::Array2::from_shape_vec((vectors.len(), 3), flat).map_or_else(
        |_| unreachable_shape(py),
        |a| numpy::IntoPyArray::into_pyarray(a, py),
    )
}

/// `from_shape_vec` fails only if the length is not rows times columns, which the callers
/// build it to be; an empty array stands in rather than a panic.
fn unreachable_shape<T: numpy::Element>(py: Python<'_>) -> Bound<'_, PyArray2<T>> {
    PyArray2::zeros(py, [0, 0], false)
}

/// A Python value as TOML: bool, int, float, str, dicts (tables) and sequences (arrays),
/// numpy scalars and arrays included. `field` names it in errors.
pub fn to_toml(value: &Bound<'_, PyAny>, field: &str) -> PyResult<toml::Value> {
    use toml::Value;
    if value.is_instance_of::<PyBool>() {
        return Ok(Value::Boolean(value.extract()?));
    }
    if let Ok(dict) = value.cast::<PyDict>() {
        let mut table = toml::Table::new();
        for (key, item) in dict.iter() {
            let key: String = key
                .extract()
                .map_err(|_| input(format!("{field}: keys must be strings")))?;
            let value = to_toml(&item, &format!("{field}.{key}"))?;
            table.insert(key, value);
        }
        return Ok(Value::Table(table));
    }
    if let Ok(text) = value.extract::<String>() {
        return Ok(Value::String(text));
    }
    // Integers first: a float is not an integer, but an integer reads as a float.
    if value.hasattr("__index__")?
        && let Ok(integer) = value.extract::<i64>()
    {
        return Ok(Value::Integer(integer));
    }
    if let Ok(number) = value.extract::<f64>() {
        return Ok(Value::Float(number));
    }
    if let Ok(items) = value.extract::<Vec<Bound<'_, PyAny>>>() {
        let items = items
            .iter()
            .enumerate()
            .map(|(i, item)| to_toml(item, &format!("{field}[{i}]")))
            .collect::<PyResult<Vec<_>>>()?;
        return Ok(Value::Array(items));
    }
    let type_name = value.get_type().name()?;
    Err(input(format!(
        "{field}: a {type_name} cannot be a scene setting (expected a number, string, bool, list or dict)"
    )))
}
