#version 330 core
// Shadow-map pass: depth only (no colour attachment).

void main() {
}
