//! The generic part of PLY reading: the header, and each element as columns of values by
//! property name (the vertex element, and the others some layouts use, such as the per-chunk
//! bounds of a compressed PLY).
//!
//! Every element before the vertex element is skipped properly, list properties included.
//! Declared counts are checked against the bytes actually present before anything is
//! allocated, so a corrupt header cannot trigger a huge allocation. ASCII rows are read one per
//! line, so a row with a value too many or too few is an error instead of shifting every later
//! value, and ASCII values must fit their declared type.

use std::collections::HashMap;

use super::PlyProblem;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    /// The type's name as PLY headers spell it.
    fn name(self) -> &'static str {
        match self {
            Self::I8 => "char",
            Self::U8 => "uchar",
            Self::I16 => "short",
            Self::U16 => "ushort",
            Self::I32 => "int",
            Self::U32 => "uint",
            Self::F32 => "float",
            Self::F64 => "double",
        }
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// The range of an integer type; `None` for floating-point types.
    pub(super) fn integer_range(self) -> Option<(f64, f64)> {
        Some(match self {
            Self::I8 => (i8::MIN.into(), i8::MAX.into()),
            Self::U8 => (0.0, u8::MAX.into()),
            Self::I16 => (i16::MIN.into(), i16::MAX.into()),
            Self::U16 => (0.0, u16::MAX.into()),
            Self::I32 => (i32::MIN.into(), i32::MAX.into()),
            Self::U32 => (0.0, u32::MAX.into()),
            Self::F32 | Self::F64 => return None,
        })
    }

    /// Whether an ASCII value can be stored in this type: integer types take only integers in
    /// their range (floating-point ones take any number; out-of-range floats become infinite and
    /// are judged by the caller).
    fn holds(self, value: f64) -> bool {
        self.integer_range().is_none_or(|(min, max)| value.fract() == 0.0 && value >= min && value <= max)
    }

    /// Decodes one value from the first `size()` bytes of `bytes` (the caller checks the length).
    fn read_binary(self, bytes: &[u8], big_endian: bool) -> f64 {
        macro_rules! conv {
            ($t:ty, $n:expr) => {{
                let arr: [u8; $n] = bytes[..$n].try_into().expect("length checked by caller");
                (if big_endian { <$t>::from_be_bytes(arr) } else { <$t>::from_le_bytes(arr) }) as f64
            }};
        }
        match self {
            Self::I8 => bytes[0] as i8 as f64,
            Self::U8 => bytes[0] as f64,
            Self::I16 => conv!(i16, 2),
            Self::U16 => conv!(u16, 2),
            Self::I32 => conv!(i32, 4),
            Self::U32 => conv!(u32, 4),
            Self::F32 => conv!(f32, 4),
            Self::F64 => conv!(f64, 8),
        }
    }
}

#[derive(Debug, Clone)]
enum Property {
    Scalar { name: String, ty: Scalar },
    List { name: String, count: Scalar, item: Scalar },
}

impl Property {
    fn name(&self) -> &str {
        match self {
            Self::Scalar { name, .. } | Self::List { name, .. } => name,
        }
    }
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

/// One scalar property of an element: its type and its values, one per row.
#[derive(Debug, Clone)]
struct Column {
    ty: Scalar,
    values: Vec<f64>,
}

/// An element of a PLY file, column by property name (list properties are skipped). Values are
/// kept in f64 so that f32 and integer properties convert back exactly.
#[derive(Debug, Clone)]
pub struct ElementTable {
    pub name: String,
    pub count: usize,
    columns: HashMap<String, Column>,
}

impl ElementTable {
    /// A column by property name.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.columns.get(name).map(|c| c.values.as_slice())
    }

    /// Every property name of the element (list properties excepted), in no order.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.columns.keys().map(String::as_str)
    }

    /// The declared type of a column.
    pub(super) fn column_type(&self, name: &str) -> Option<Scalar> {
        self.columns.get(name).map(|c| c.ty)
    }

    pub(super) fn require(&self, name: &str) -> Result<&[f64], PlyProblem> {
        self.column(name).ok_or_else(|| PlyProblem::MissingProperty(name.to_string()))
    }
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    data_start: usize,
}

fn parse_header(bytes: &[u8]) -> Result<Header, PlyProblem> {
    let mut pos = 0;
    let mut line_no = 0;
    let next_line = |pos: &mut usize| -> Option<String> {
        let rest = &bytes[*pos..];
        let end = rest.iter().position(|&b| b == b'\n')?;
        *pos += end + 1;
        Some(String::from_utf8_lossy(&rest[..end]).trim_end_matches('\r').to_string())
    };
    if next_line(&mut pos).as_deref().map(str::trim) != Some("ply") {
        return Err(PlyProblem::NotPly);
    }
    let header_err = |line: usize, message: &str| PlyProblem::Header { line, message: message.to_string() };
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        line_no += 1;
        let line = next_line(&mut pos).ok_or_else(|| header_err(line_no + 1, "header has no `end_header`"))?;
        let words: Vec<&str> = line.split_whitespace().collect();
        let scalar =
            |name: &str| Scalar::parse(name).ok_or_else(|| header_err(line_no + 1, &format!("unknown type `{name}`")));
        let property = match words.as_slice() {
            ["end_header"] => break,
            ["comment", ..] | ["obj_info", ..] | [] => continue,
            ["format", fmt, _version] => {
                encoding = Some(match *fmt {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLittleEndian,
                    "binary_big_endian" => Encoding::BinaryBigEndian,
                    _ => return Err(header_err(line_no + 1, &format!("unknown format `{fmt}`"))),
                });
                continue;
            }
            ["element", name, count] => {
                let count =
                    count.parse().map_err(|_| header_err(line_no + 1, &format!("bad element count `{count}`")))?;
                elements.push(Element { name: name.to_string(), count, properties: Vec::new() });
                continue;
            }
            ["property", "list", count_ty, item_ty, name] => {
                let count = scalar(count_ty)?;
                if count.integer_range().is_none() {
                    return Err(header_err(
                        line_no + 1,
                        &format!("list `{name}` has count type `{count_ty}`, which is not an integer type"),
                    ));
                }
                Property::List { name: name.to_string(), count, item: scalar(item_ty)? }
            }
            ["property", ty, name] => Property::Scalar { name: name.to_string(), ty: scalar(ty)? },
            _ => return Err(header_err(line_no + 1, &format!("unexpected line `{line}`"))),
        };
        let element = elements.last_mut().ok_or_else(|| header_err(line_no + 1, "property before any element"))?;
        if element.properties.iter().any(|p| p.name() == property.name()) {
            return Err(header_err(
                line_no + 1,
                &format!("element `{}` declares property `{}` twice", element.name, property.name()),
            ));
        }
        element.properties.push(property);
    }
    let encoding = encoding.ok_or_else(|| header_err(1, "no `format` line"))?;
    Ok(Header { encoding, elements, data_start: pos })
}

/// Reads values one row at a time from the data part of a PLY file.
enum Cursor<'a> {
    /// ASCII data: `rest` is the text after the current row, `row` the current row's values.
    Ascii {
        rest: &'a str,
        row: std::str::SplitAsciiWhitespace<'a>,
    },
    Binary {
        data: &'a [u8],
        big_endian: bool,
    },
}

impl<'a> Cursor<'a> {
    fn new(encoding: Encoding, data: &'a [u8]) -> Result<Self, PlyProblem> {
        Ok(match encoding {
            Encoding::Ascii => {
                let rest = std::str::from_utf8(data).map_err(|e| PlyProblem::BadValue {
                    element: "data".into(),
                    row: 0,
                    message: format!("ASCII data is not UTF-8 (byte {} of the data)", e.valid_up_to()),
                })?;
                Cursor::Ascii { rest, row: "".split_ascii_whitespace() }
            }
            Encoding::BinaryLittleEndian => Cursor::Binary { data, big_endian: false },
            Encoding::BinaryBigEndian => Cursor::Binary { data, big_endian: true },
        })
    }

    /// Bytes of data left.
    fn remaining(&self) -> usize {
        match self {
            Self::Ascii { rest, .. } => rest.len(),
            Self::Binary { data, .. } => data.len(),
        }
    }

    /// How many rows of at most `values` values each (scalars and list counts) the data left
    /// can hold at most: a binary row takes `min_bytes`, an ASCII value at least one character
    /// and a separator (the last row may lack its line break).
    fn max_rows(&self, values: usize, min_bytes: usize) -> usize {
        match self {
            Self::Ascii { rest, .. } => (rest.len() + 1) / (2 * values.max(1)),
            Self::Binary { data, .. } => data.len() / min_bytes.max(1),
        }
    }

    /// Starts a row: for ASCII, moves to the next line that is not blank.
    fn start_row(&mut self) {
        if let Self::Ascii { rest, row } = self {
            while !rest.is_empty() {
                let (line, after) = rest.split_once('\n').unwrap_or((rest, ""));
                *rest = after;
                if !line.trim().is_empty() {
                    *row = line.split_ascii_whitespace();
                    return;
                }
            }
            *row = "".split_ascii_whitespace();
        }
    }

    /// Ends a row: an ASCII line with values left over holds more than the header declares.
    fn end_row(&mut self) -> Result<(), String> {
        match self {
            Self::Ascii { row, .. } => match row.next() {
                Some(extra) => Err(format!("the line has more values than the header declares (`{extra}` is extra)")),
                None => Ok(()),
            },
            Self::Binary { .. } => Ok(()),
        }
    }

    /// The next value of the row; `Ok(None)` when the data ends, `Err` when a token is not a
    /// number of the declared type or an ASCII line ends early.
    fn next(&mut self, ty: Scalar) -> Result<Option<f64>, String> {
        match self {
            Self::Ascii { rest, row } => match row.next() {
                None if rest.trim().is_empty() => Ok(None),
                None => Err("the line has fewer values than the header declares".into()),
                Some(token) => {
                    let value: f64 = token.parse().map_err(|_| format!("`{token}` is not a number"))?;
                    if ty.holds(value) {
                        Ok(Some(value))
                    } else {
                        Err(format!("`{token}` is not a `{}` value", ty.name()))
                    }
                }
            },
            Self::Binary { data, big_endian } => {
                if data.len() < ty.size() {
                    return Ok(None);
                }
                let value = ty.read_binary(data, *big_endian);
                *data = &data[ty.size()..];
                Ok(Some(value))
            }
        }
    }
}

/// Reads the vertex element of a PLY file held in memory.
pub fn read_vertex_table(bytes: &[u8]) -> Result<ElementTable, PlyProblem> {
    read_tables(bytes)?.into_iter().find(|t| t.name == "vertex").ok_or(PlyProblem::NoVertexElement)
}

/// Reads every element of a PLY file held in memory, in file order, up to and including the
/// last one that has scalar properties (the data after it is not read).
pub fn read_tables(bytes: &[u8]) -> Result<Vec<ElementTable>, PlyProblem> {
    let header = parse_header(bytes)?;
    let mut cursor = Cursor::new(header.encoding, &bytes[header.data_start..])?;
    let has_scalars = |e: &Element| e.properties.iter().any(|p| matches!(p, Property::Scalar { .. }));
    let last = header.elements.iter().rposition(has_scalars);
    let mut tables = Vec::new();
    for element in &header.elements[..last.map_or(0, |i| i + 1)] {
        // Bound the allocation by what the file can hold.
        let min_bytes = element
            .properties
            .iter()
            .map(|p| match p {
                Property::Scalar { ty, .. } => ty.size(),
                Property::List { count, .. } => count.size(),
            })
            .sum::<usize>();
        let max_rows = cursor.max_rows(element.properties.len(), min_bytes);
        if element.count > max_rows {
            return Err(PlyProblem::CountTooLarge {
                element: element.name.clone(),
                count: element.count,
                bytes: cursor.remaining(),
                max_rows,
            });
        }
        let scalars = element.properties.iter().filter_map(|p| match p {
            Property::Scalar { ty, .. } => Some(Column { ty: *ty, values: Vec::with_capacity(element.count) }),
            Property::List { .. } => None,
        });
        let mut columns: Vec<Column> = scalars.collect();
        // Rows without properties hold nothing to read (and in ASCII no line to skip).
        let rows = if element.properties.is_empty() { 0 } else { element.count };
        for row in 0..rows {
            let bad = |message: String| PlyProblem::BadValue { element: element.name.clone(), row, message };
            let read = |cursor: &mut Cursor, ty: Scalar| {
                cursor.next(ty).map_err(bad)?.ok_or_else(|| PlyProblem::Truncated {
                    element: element.name.clone(),
                    row,
                    count: element.count,
                })
            };
            cursor.start_row();
            let mut column = 0;
            for property in &element.properties {
                match property {
                    Property::Scalar { ty, .. } => {
                        columns[column].values.push(read(&mut cursor, *ty)?);
                        column += 1;
                    }
                    Property::List { name, count, item } => {
                        let n = read(&mut cursor, *count)?;
                        if !(n >= 0.0) {
                            return Err(bad(format!("list `{name}` has length {n}")));
                        }
                        for _ in 0..n as u64 {
                            read(&mut cursor, *item)?;
                        }
                    }
                }
            }
            cursor.end_row().map_err(bad)?;
        }
        let names = element.properties.iter().filter_map(|p| match p {
            Property::Scalar { name, .. } => Some(name.clone()),
            Property::List { .. } => None,
        });
        let columns = names.zip(columns).collect();
        tables.push(ElementTable { name: element.name.clone(), count: element.count, columns });
    }
    Ok(tables)
}
