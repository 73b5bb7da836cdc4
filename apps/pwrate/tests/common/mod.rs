//! What the server's tests share: a small study on disk, a server started on a free port, and
//! one-shot HTTP requests (no client library: HTTP/1.1 with `Connection: close`).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};

/// A study of 2 views (96 x 64) with the ground truth and two methods.
pub fn study(dir: &std::path::Path) {
    for folder in ["gt", "blurry", "sharp"] {
        std::fs::create_dir_all(dir.join(folder)).unwrap();
        for (v, shade) in [("a.png", 40u8), ("b.png", 200)] {
            let img = image::RgbImage::from_pixel(96, 64, image::Rgb([shade, shade, shade]));
            img.save(dir.join(folder).join(v)).unwrap();
        }
    }
}

/// One HTTP/1.1 request; the status code and the body (read to its `Content-Length`: a server
/// may keep the connection open whatever the request asks).
pub fn request(port: u16, method: &str, path: &str, body: &str) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let mut reader = BufReader::new(s);
    let mut status_line = String::new();
    reader.read_line(&mut status_line).unwrap();
    let status = status_line.split(' ').nth(1).unwrap().parse().unwrap();
    let mut length = None;
    loop {
        let mut line = String::new();
        reader.read_line(&mut line).unwrap();
        let line = line.trim_end();
        if line.is_empty() {
            break;
        }
        if let Some((name, value)) = line.split_once(':')
            && name.eq_ignore_ascii_case("content-length")
        {
            length = value.trim().parse::<usize>().ok();
        }
    }
    let mut payload = Vec::new();
    match length {
        Some(n) => {
            payload.resize(n, 0);
            reader.read_exact(&mut payload).unwrap();
        }
        None => {
            reader.read_to_end(&mut payload).unwrap();
        }
    }
    (status, payload)
}

/// `pwrate serve` of `root` on a free port, appending to `judgments`; the child and its port.
pub fn start_server(root: &Path, judgments: &Path) -> (Child, u16) {
    let mut server = Command::new(env!("CARGO_BIN_EXE_pwrate"))
        .args(["serve", root.to_str().unwrap(), "--judgments", judgments.to_str().unwrap(), "--port", "0"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(server.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let port = line.trim().rsplit(':').next().unwrap().parse().unwrap_or_else(|_| panic!("{line}"));
    (server, port)
}
