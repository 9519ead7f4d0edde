#version 430
// Depth pre-pass: no colour output (colour writes are masked off during this pass).
void main() {
}
