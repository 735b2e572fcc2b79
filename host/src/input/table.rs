//! CSV with `#` comments and columns found by name, with errors that point at the cell.
use std::fmt;
use std::path::{Path, PathBuf};

/// A bad input file: where, and what was expected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct InputError {
    pub path: PathBuf,
    /// 1-based line number, when the problem is on one line.
    pub line: Option<u64>,
    /// 1-based column (CSV field) and its header name, when the problem is in one cell.
    pub column: Option<(usize, String)>,
    pub message: String,
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some((index, name)) = &self.column {
            write!(f, ": column {index} ({name})")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl InputError {
    pub fn file(path: &Path, message: impl Into<String>) -> Self {
        InputError { path: path.to_owned(), line: None, column: None, message: message.into() }
    }

    pub fn at_line(path: &Path, line: u64, message: impl Into<String>) -> Self {
        InputError { line: Some(line), ..InputError::file(path, message) }
    }
}

/// One data line of the table.
#[derive(Debug, Clone)]
pub struct Row {
    pub line: u64,
    pub fields: csv::StringRecord,
}

/// A CSV table: the `#` lines before the header, the header, and the data rows, read one at
/// a time by [`Table::for_each_row`] into one reused record (collecting a record per row
/// was a quarter of a 20,000-sample fit).
#[derive(Debug, Clone)]
pub struct Table<'a> {
    pub path: PathBuf,
    /// (line, text after `#`) for each comment line before the header.
    pub preamble: Vec<(u64, String)>,
    pub header: Vec<String>,
    pub header_line: u64,
    text: &'a str,
}

impl<'a> Table<'a> {
    /// Parses the header of `text`, read from `path` (named in errors).
    pub fn parse(path: &Path, text: &'a str) -> Result<Table<'a>, InputError> {
        if text.trim().is_empty() {
            return Err(InputError::file(path, "the file is empty"));
        }
        let mut preamble = Vec::new();
        let mut header_line = None;
        for (index, line) in text.lines().enumerate() {
            let number = index as u64 + 1;
            let trimmed = line.trim();
            if let Some(comment) = trimmed.strip_prefix('#') {
                preamble.push((number, comment.trim().to_owned()));
            } else if !trimmed.is_empty() {
                header_line = Some(number);
                break;
            }
        }
        let header_line =
            header_line.ok_or_else(|| InputError::file(path, "no header line: the file has only comments"))?;

        let mut reader = Self::reader(text);
        let mut header_record = csv::StringRecord::new();
        match reader.read_record(&mut header_record) {
            Ok(true) => {}
            Ok(false) => return Err(InputError::file(path, "no header line")),
            Err(error) => return Err(csv_error(path, error)),
        }
        let header: Vec<String> = header_record.iter().map(str::to_owned).collect();
        for (index, name) in header.iter().enumerate() {
            if name.is_empty() {
                return Err(InputError {
                    column: Some((index + 1, String::new())),
                    ..InputError::at_line(path, header_line, "empty column name in the header")
                });
            }
            if header[..index].contains(name) {
                return Err(InputError {
                    column: Some((index + 1, name.clone())),
                    ..InputError::at_line(path, header_line, "column appears twice in the header")
                });
            }
        }
        Ok(Table { path: path.to_owned(), preamble, header, header_line, text })
    }

    fn reader(text: &str) -> csv::Reader<&[u8]> {
        csv::ReaderBuilder::new()
            .has_headers(false)
            .comment(Some(b'#'))
            .flexible(true)
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes())
    }

    /// Calls `each` with every data row in order; blank rows are skipped, a row with another
    /// number of fields than the header is an error.
    pub fn for_each_row(&self, mut each: impl FnMut(&Row) -> Result<(), InputError>) -> Result<(), InputError> {
        let mut reader = Self::reader(self.text);
        let mut row = Row { line: 0, fields: csv::StringRecord::new() };
        let mut header_seen = false;
        loop {
            match reader.read_record(&mut row.fields) {
                Ok(true) => {}
                Ok(false) => return Ok(()),
                Err(error) => return Err(csv_error(&self.path, error)),
            }
            if !header_seen {
                header_seen = true;
                continue;
            }
            row.line = row.fields.position().map_or(0, |p| p.line());
            if row.fields.iter().all(str::is_empty) {
                continue;
            }
            if row.fields.len() != self.header.len() {
                return Err(InputError::at_line(
                    &self.path,
                    row.line,
                    format!(
                        "expected {} fields as in the header ({}), found {}",
                        self.header.len(),
                        self.header.join(","),
                        row.fields.len()
                    ),
                ));
            }
            each(&row)?;
        }
    }

    /// Index of the column called `name`.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    /// Index of a column that must be there.
    pub fn required_column(&self, name: &str, what: &str) -> Result<usize, InputError> {
        self.column(name).ok_or_else(|| {
            InputError::at_line(
                &self.path,
                self.header_line,
                format!("missing column `{name}` ({what}); the header has: {}", self.header.join(",")),
            )
        })
    }

    /// An error about cell (`row`, `column`).
    pub fn cell_error(&self, row: &Row, column: usize, message: impl Into<String>) -> InputError {
        InputError {
            column: Some((column + 1, self.header.get(column).cloned().unwrap_or_default())),
            ..InputError::at_line(&self.path, row.line, message)
        }
    }

    /// The finite number in cell (`row`, `column`).
    pub fn number(&self, row: &Row, column: usize) -> Result<f64, InputError> {
        let text = row.fields.get(column).unwrap_or("");
        match text.parse::<f64>() {
            Ok(value) if value.is_finite() => Ok(value),
            Ok(_) => Err(self.cell_error(row, column, format!("expected a finite number, found {text:?}"))),
            Err(_) => Err(self.cell_error(row, column, format!("expected a number, found {text:?}"))),
        }
    }
}

fn csv_error(path: &Path, error: csv::Error) -> InputError {
    let line = error.position().map(|p| p.line());
    let message = match error.kind() {
        csv::ErrorKind::Utf8 { .. } => "the file is not valid UTF-8 text".to_owned(),
        _ => format!("unreadable CSV: {error}"),
    };
    InputError { line, ..InputError::file(path, message) }
}

/// Reads `path` to a string, with an [`InputError`] that names it.
pub fn read_text(path: &Path) -> Result<String, InputError> {
    let bytes = std::fs::read(path).map_err(|e| InputError::file(path, format!("cannot read: {e}")))?;
    String::from_utf8(bytes).map_err(|e| {
        let offset = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..offset].iter().filter(|&&b| b == b'\n').count() as u64 + 1;
        InputError::at_line(path, line, "the file is not valid UTF-8 text")
    })
}
