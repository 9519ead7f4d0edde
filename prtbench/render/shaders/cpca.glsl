// Clustered-PCA transfer (Sloan 2003; prtbench/compress): per vertex a cluster id and
// PCA_VECTORS weights, per cluster the light projected onto its mean and basis by the CPU
// each frame, P = (K, 1 + n', CPCA_OUTPUTS, 3) floats. Output o of vertex v in cluster c:
// P[c][0][o] + sum_j w[v][j] P[c][1 + j][o]  (Sloan's per-vertex n'-term dot product).
// Defines: CPCA_CLUSTERS (K), PCA_VECTORS (n'), CPCA_OUTPUTS (vec3 outputs per vertex).
// Bindings (prtbench/compress/buffers.py): 3 cluster ids (K > 1), 4 weights (n' > 0), 5 P.
#if CPCA_CLUSTERS > 1
layout(std430, binding = 3) readonly buffer CpcaCluster { int cpca_cluster[]; };
#endif
#if PCA_VECTORS > 0
layout(std430, binding = 4) readonly buffer CpcaWeights { float cpca_weights[]; };
#endif
layout(std430, binding = 5) readonly buffer CpcaProjected { float cpca_projected[]; };

int cpca_cluster_of(int vertex) {
#if CPCA_CLUSTERS > 1
    return cpca_cluster[vertex];
#else
    return 0;
#endif
}

vec3 cpca_table(int index) {
    return vec3(cpca_projected[3 * index], cpca_projected[3 * index + 1],
                cpca_projected[3 * index + 2]);
}

vec3 cpca_output(int vertex, int cluster, int o) {
    int base = cluster * (1 + PCA_VECTORS) * CPCA_OUTPUTS + o;
    vec3 sum = cpca_table(base);
#if PCA_VECTORS > 0
    for (int j = 0; j < PCA_VECTORS; ++j) {
        sum += cpca_weights[vertex * PCA_VECTORS + j] * cpca_table(base + (1 + j) * CPCA_OUTPUTS);
    }
#endif
    return sum;
}
