//! CSV with `#` comments and columns found by name, with errors that point at the cell.
//!
//! One path for every table (loop tables, recordings, `simulate --motion FILE.csv`): the bytes
//! go through [`Normalised`] first — a UTF-8 byte-order mark removed, CR-only and CRLF line
//! endings made LF, the blanks before the `#` of an indented comment line and blank-only lines
//! removed — and then both the preamble scan and the csv reader see the same lines, with the
//! same line numbers. A file is streamed, never held whole in memory.
use std::fmt;
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
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
    /// The fields as written; [`Row::field`] trims them.
    pub fields: csv::StringRecord,
}

impl Row {
    /// Field `column` without the blanks around it ("" beyond the last).
    pub fn field(&self, column: usize) -> &str {
        self.fields.get(column).unwrap_or("").trim()
    }
}

/// Where a table's text comes from: read again from the start for each pass.
#[derive(Debug, Clone)]
enum Source<'a> {
    Bytes(&'a [u8]),
    File,
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
    source: Source<'a>,
}

/// Blanks before a `#` longer than this are kept: such a line is data, not an indented comment.
const MAX_INDENT: usize = 4096;

/// The bytes every table reader sees (see the module's documentation): a [`Read`] adapter, so
/// a file is normalised as it streams. Line numbers are kept: `\r\n`, `\r` and `\n` each end
/// exactly one line.
pub struct Normalised<R> {
    inner: R,
    /// Normalised bytes not yet handed out, from `out[at..]`.
    out: Vec<u8>,
    at: usize,
    /// Nothing read yet (a byte-order mark may follow).
    start: bool,
    state: LineState,
}

/// Where the normaliser is in its input, between two bytes.
struct LineState {
    /// At the start of a line; `indent` holds its blanks so far.
    line_start: bool,
    indent: Vec<u8>,
    /// The previous byte was a `\r` (a `\n` right after it ends no further line).
    after_cr: bool,
}

impl<R: BufRead> Normalised<R> {
    pub fn new(inner: R) -> Self {
        let state = LineState { line_start: true, indent: Vec::new(), after_cr: false };
        Normalised { inner, out: Vec::new(), at: 0, start: true, state }
    }

    /// Normalises the next chunk of `inner` into `out`; false at the end of the input.
    fn refill(&mut self) -> std::io::Result<bool> {
        self.out.clear();
        self.at = 0;
        while self.out.is_empty() {
            if self.start {
                self.start = false;
                let mut bom = [0u8; 3];
                let mut len = 0;
                while len < 3 {
                    let n = self.inner.read(&mut bom[len..])?;
                    if n == 0 {
                        break;
                    }
                    len += n;
                }
                if bom[..len] != [0xef, 0xbb, 0xbf] {
                    self.state.push(&mut self.out, &bom[..len]);
                }
                continue;
            }
            let chunk = self.inner.fill_buf()?;
            if chunk.is_empty() {
                // A last line without its line ending: its blanks are content.
                self.out.append(&mut self.state.indent);
                return Ok(!self.out.is_empty());
            }
            let len = chunk.len();
            self.state.push(&mut self.out, chunk);
            self.inner.consume(len);
        }
        Ok(true)
    }
}

impl LineState {
    /// Normalises `bytes`, the next of the input, onto `out`.
    fn push(&mut self, out: &mut Vec<u8>, mut bytes: &[u8]) {
        while let Some((&byte, rest)) = bytes.split_first() {
            if !self.line_start {
                // Inside a line: everything up to its end is copied as it is.
                let end = memchr::memchr2(b'\n', b'\r', bytes).unwrap_or(bytes.len());
                if end > 0 {
                    out.extend_from_slice(&bytes[..end]);
                    bytes = &bytes[end..];
                    continue;
                }
            }
            bytes = rest;
            let after_cr = std::mem::replace(&mut self.after_cr, false);
            match byte {
                b'\n' if after_cr => {}
                b'\n' | b'\r' => {
                    // A blank-only line becomes an empty one.
                    self.indent.clear();
                    out.push(b'\n');
                    self.line_start = true;
                    self.after_cr = byte == b'\r';
                }
                b' ' | b'\t' if self.line_start && self.indent.len() < MAX_INDENT => self.indent.push(byte),
                _ if self.line_start => {
                    self.line_start = false;
                    if byte != b'#' {
                        out.append(&mut self.indent);
                    }
                    self.indent.clear();
                    out.push(byte);
                }
                _ => out.push(byte),
            }
        }
    }
}

impl<R: BufRead> Read for Normalised<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.at >= self.out.len() && !self.refill()? {
            return Ok(0);
        }
        let available = self.out.get(self.at..).unwrap_or_default();
        let n = available.len().min(buf.len());
        buf[..n].copy_from_slice(&available[..n]);
        self.at += n;
        Ok(n)
    }
}

fn open(path: &Path) -> Result<File, InputError> {
    File::open(path).map_err(|e| InputError::file(path, format!("cannot read: {e}")))
}

impl<'a> Table<'a> {
    /// Parses the header of `text`, read from `path` (named in errors).
    pub fn parse(path: &Path, text: &'a str) -> Result<Table<'a>, InputError> {
        Table::scan(path, Source::Bytes(text.as_bytes()))
    }

    /// [`Table::parse`] of bytes that may not be UTF-8 text (an error then names the line).
    pub fn parse_bytes(path: &Path, bytes: &'a [u8]) -> Result<Table<'a>, InputError> {
        Table::scan(path, Source::Bytes(bytes))
    }

    /// Opens the table in the file `path` and parses its header; the rows are streamed from
    /// the file by [`Table::for_each_row`].
    pub fn open(path: &Path) -> Result<Table<'static>, InputError> {
        Table::scan(path, Source::File)
    }

    /// The normalised bytes of the table, from the start.
    fn bytes(path: &Path, source: &Source<'a>) -> Result<Box<dyn Read + 'a>, InputError> {
        Ok(match source {
            Source::Bytes(bytes) => Box::new(Normalised::new(*bytes)),
            Source::File => Box::new(Normalised::new(BufReader::with_capacity(1 << 16, open(path)?))),
        })
    }

    fn scan(path: &Path, source: Source<'a>) -> Result<Table<'a>, InputError> {
        let mut lines = BufReader::new(Table::bytes(path, &source)?);
        let mut preamble = Vec::new();
        let mut header_line = None;
        let mut line = Vec::new();
        let mut number = 0;
        let mut any_content = false;
        loop {
            line.clear();
            let read =
                lines.read_until(b'\n', &mut line).map_err(|e| InputError::file(path, format!("cannot read: {e}")))?;
            if read == 0 {
                break;
            }
            number += 1;
            let text = std::str::from_utf8(&line)
                .map_err(|_| InputError::at_line(path, number, "the file is not valid UTF-8 text"))?;
            let trimmed = text.trim();
            any_content |= !trimmed.is_empty();
            if let Some(comment) = trimmed.strip_prefix('#') {
                preamble.push((number, comment.trim().to_owned()));
            } else if !trimmed.is_empty() {
                header_line = Some(number);
                break;
            }
        }
        if !any_content {
            return Err(InputError::file(path, "the file is empty"));
        }
        let header_line =
            header_line.ok_or_else(|| InputError::file(path, "no header line: the file has only comments"))?;
        drop(lines);

        let mut reader = Self::reader(Table::bytes(path, &source)?);
        let mut header_record = csv::StringRecord::new();
        match reader.read_record(&mut header_record) {
            Ok(true) => {}
            Ok(false) => return Err(InputError::file(path, "no header line")),
            Err(error) => return Err(csv_error(path, error)),
        }
        let header: Vec<String> = header_record.iter().map(|name| name.trim().to_owned()).collect();
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
        Ok(Table { path: path.to_owned(), preamble, header, header_line, source })
    }

    /// The csv reader of the normalised bytes. Fields are trimmed where they are read
    /// ([`Row::field`]): the reader's own trimming builds a new record for every row, a tenth of
    /// reading a long recording.
    fn reader<R: Read>(bytes: R) -> csv::Reader<R> {
        csv::ReaderBuilder::new()
            .has_headers(false)
            .comment(Some(b'#'))
            .flexible(true)
            .buffer_capacity(1 << 16)
            .from_reader(bytes)
    }

    /// Calls `each` with every data row in order; blank lines are skipped, a row with another
    /// number of fields than the header is an error. A row of empty fields (`,,,`) is not blank:
    /// its fields are read, and the first that must hold a number says so.
    pub fn for_each_row(&self, mut each: impl FnMut(&Row) -> Result<(), InputError>) -> Result<(), InputError> {
        let mut reader = Self::reader(Table::bytes(&self.path, &self.source)?);
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
            if row.fields.len() == 1 && row.fields.iter().all(|field| field.trim().is_empty()) {
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
        let text = row.field(column);
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
