#version 430
// Depth pre-pass: depth only, so the shading pass runs once per visible pixel.
void main() {}
