//! The system's file dialog for opening a stream (rfd: the XDG desktop portal, else zenity),
//! on its own thread so that the window keeps drawing while the dialog is open.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, TryRecvError, channel};

use eframe::egui;

/// An open file dialog, or none.
#[derive(Default)]
pub struct FileDialog {
    pending: Option<Receiver<Option<PathBuf>>>,
}

/// How a dialog ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Choice {
    Chosen(PathBuf),
    /// Closed without a file, or no dialog could be shown (rfd does not tell the two apart).
    None,
}

impl FileDialog {
    /// Shows the dialog, starting in `near`'s folder when it names an existing file or folder.
    pub fn open(&mut self, near: &Path, ctx: &egui::Context) {
        let (sender, receiver) = channel();
        let start = if near.is_dir() { Some(near.to_path_buf()) } else { near.parent().map(Path::to_path_buf) };
        let start = start.filter(|d| d.is_dir());
        let ctx = ctx.clone();
        std::thread::spawn(move || {
            let mut dialog = rfd::FileDialog::new().set_title("Open a pwgs stream").add_filter("pwgs stream", &["pwb"]);
            if let Some(dir) = start {
                dialog = dialog.set_directory(dir);
            }
            // The window may have closed; then no one waits for the choice.
            let _ = sender.send(dialog.pick_file());
            ctx.request_repaint();
        });
        self.pending = Some(receiver);
    }

    pub fn is_open(&self) -> bool {
        self.pending.is_some()
    }

    /// How the dialog ended, once it has; `None` while it is open or when none was opened.
    pub fn poll(&mut self) -> Option<Choice> {
        let receiver = self.pending.as_ref()?;
        let choice = match receiver.try_recv() {
            Ok(Some(path)) => Choice::Chosen(path),
            Ok(None) | Err(TryRecvError::Disconnected) => Choice::None,
            Err(TryRecvError::Empty) => return None,
        };
        self.pending = None;
        Some(choice)
    }
}
