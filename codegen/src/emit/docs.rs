//! Documentation text for the emitted module: every line made safe to print as a `///` or
//! `//!` line, names escaped as data (Markdown) and the description fenced as plain text.

use proc_macro2::Span;
use syn::{Expr, parse_quote};

/// `text` as documentation shows it safely: every character a comment cannot hold as it is
/// (controls, bidi and other invisible format characters, line separators) as a visible
/// `\u{…}` escape, and tabs as four spaces (clippy's `tabs_in_doc_comments`). Validation
/// refuses most of these; this holds for any text.
pub(super) fn doc_safe(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        if c == '\t' {
            out.push_str("    ");
        } else if crate::validate::names::hidden(c) {
            out.push_str(&format!("\\u{{{:04x}}}", u32::from(c)));
        } else {
            out.push(c);
        }
    }
    out
}

/// `text` with a backslash before each character Markdown reads as markup inside a line
/// (code spans, links, images, HTML, emphasis), so rustdoc shows names as the plain text
/// they are.
pub(super) fn markdown_escaped(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        if matches!(c, '\\' | '`' | '*' | '<' | '>' | '[' | ']' | '&' | '~' | '|') {
            out.push('\\');
        }
        out.push(c);
    }
    out
}

/// A description as documentation lines: a fenced `text` block whose fence is longer than
/// any run of backticks in it, so nothing in it is Markdown (no code block rustdoc would run
/// as a doctest, no HTML, no link) and no line of it can close the block.
pub(super) fn fenced(description: &str) -> Vec<String> {
    let longest = description.split(|c| c != '`').map(str::len).max().unwrap_or(0);
    let fence = "`".repeat(longest.max(2) + 1);
    let mut lines = vec![format!(" {fence}text")];
    lines.extend(description.split("\r\n").flat_map(|l| l.split(['\n', '\r'])).map(|l| {
        let l = doc_safe(l);
        if l.is_empty() { l } else { format!(" {l}") }
    }));
    lines.push(format!(" {fence}"));
    lines
}

/// One `#[doc = "…"]` attribute per line, each line a string literal (made safe by
/// [`doc_safe`]); inner (`//!`) or outer (`///`) as prettyplease prints them.
pub(super) fn doc_attributes(lines: &[String], inner: bool) -> Vec<syn::Attribute> {
    lines
        .iter()
        .map(|line| {
            let lit = syn::LitStr::new(&doc_safe(line), Span::call_site());
            if inner { parse_quote!(#![doc = #lit]) } else { parse_quote!(#[doc = #lit]) }
        })
        .collect()
}

/// Rewrites every `#[doc]` attribute of a top-level item (and of an impl's items) as one
/// attribute per line made safe by [`doc_safe`], so prettyplease prints `///` lines and never
/// a `/** … */` block, which a `*/` in the text would end.
pub(super) fn one_line_docs(item: &mut syn::Item) {
    fn split(attrs: &mut Vec<syn::Attribute>) {
        if !attrs.iter().any(|a| doc_of(a).is_some()) {
            return;
        }
        let mut out = Vec::with_capacity(attrs.len());
        for attr in attrs.drain(..) {
            match doc_of(&attr) {
                Some(doc) => {
                    let lines: Vec<String> = doc.lines().map(str::to_owned).collect();
                    out.extend(doc_attributes(&lines, false));
                }
                None => out.push(attr),
            }
        }
        *attrs = out;
    }
    match item {
        syn::Item::Fn(f) => split(&mut f.attrs),
        syn::Item::Const(c) => split(&mut c.attrs),
        syn::Item::Static(s) => split(&mut s.attrs),
        syn::Item::Struct(s) => split(&mut s.attrs),
        syn::Item::Impl(i) => {
            split(&mut i.attrs);
            for item in &mut i.items {
                if let syn::ImplItem::Fn(f) = item {
                    split(&mut f.attrs);
                }
            }
        }
        _ => {}
    }
}

/// The text of a `#[doc = "…"]` attribute.
pub(super) fn doc_of(attr: &syn::Attribute) -> Option<String> {
    match &attr.meta {
        syn::Meta::NameValue(m) if m.path.is_ident("doc") => match &m.value {
            Expr::Lit(syn::ExprLit { lit: syn::Lit::Str(s), .. }) => Some(s.value()),
            _ => None,
        },
        _ => None,
    }
}
