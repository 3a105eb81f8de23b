//! A minimal MATLAB level-5 MAT-file writer for tests: uncompressed real double vectors and
//! matrices, and char (text) variables, laid out as the MAT-file format reference describes
//! (128-byte header, then one miMATRIX element per variable, every element 8-byte aligned).
#![allow(dead_code)]

/// A variable to write.
pub enum Var<'a> {
    /// Real doubles, column-major, with the given dimensions.
    Double { name: &'a str, dims: [usize; 2], data: &'a [f64] },
    /// Text (mxCHAR_CLASS, UTF-16 code units as miUINT16).
    Text { name: &'a str, text: &'a str },
}

const MI_INT8: u32 = 1;
const MI_UINT16: u32 = 4;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_DOUBLE: u32 = 9;
const MI_MATRIX: u32 = 14;
const MX_CHAR: u32 = 4;
const MX_DOUBLE: u32 = 6;

fn pad8(v: &mut Vec<u8>) {
    while !v.len().is_multiple_of(8) {
        v.push(0);
    }
}

fn element(out: &mut Vec<u8>, ty: u32, payload: &[u8]) {
    out.extend_from_slice(&ty.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    out.extend_from_slice(payload);
    pad8(out);
}

fn matrix(class: u32, name: &str, dims: [usize; 2], ty: u32, payload: &[u8]) -> Vec<u8> {
    let mut sub = Vec::new();
    let flags = [class.to_le_bytes(), 0u32.to_le_bytes()].concat();
    element(&mut sub, MI_UINT32, &flags);
    let d: Vec<u8> = dims.iter().flat_map(|&x| (x as i32).to_le_bytes()).collect();
    element(&mut sub, MI_INT32, &d);
    element(&mut sub, MI_INT8, name.as_bytes());
    element(&mut sub, ty, payload);
    let mut out = Vec::new();
    element(&mut out, MI_MATRIX, &sub);
    out
}

/// The bytes of a level-5 MAT-file holding `vars`.
pub fn level5(vars: &[Var]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut text = b"MATLAB 5.0 MAT-file, written by the oesweep tests".to_vec();
    text.resize(116, b' ');
    out.extend_from_slice(&text);
    out.extend_from_slice(&[0u8; 8]);
    out.extend_from_slice(&0x0100u16.to_le_bytes());
    out.extend_from_slice(b"IM");
    for v in vars {
        match v {
            Var::Double { name, dims, data } => {
                assert_eq!(dims[0] * dims[1], data.len());
                let payload: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
                out.extend(matrix(MX_DOUBLE, name, *dims, MI_DOUBLE, &payload));
            }
            Var::Text { name, text } => {
                let units: Vec<u16> = text.encode_utf16().collect();
                let payload: Vec<u8> = units.iter().flat_map(|x| x.to_le_bytes()).collect();
                out.extend(matrix(MX_CHAR, name, [1, units.len()], MI_UINT16, &payload));
            }
        }
    }
    out
}

/// The first bytes of a v7.3 MAT-file: the 512-byte user block with MATLAB's header text,
/// then the HDF5 signature (the rest does not matter for the refusal).
pub fn v73_stub() -> Vec<u8> {
    let mut out =
        b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Nov 23 10:00:00 2026 HDF5 schema 1.00 .".to_vec();
    out.resize(116, b' ');
    out.extend_from_slice(&[0u8; 8]);
    out.extend_from_slice(&0x0200u16.to_le_bytes());
    out.extend_from_slice(b"IM");
    out.resize(512, 0);
    out.extend_from_slice(b"\x89HDF\r\n\x1a\n");
    out.resize(2048, 0);
    out
}
