#version 430
// Early depth pre-pass of the learnt transfer: depth only (colour writes are masked off), so
// the network runs once per visible pixel in the shading pass (thesis §4.1.4.1).
void main() {
}
