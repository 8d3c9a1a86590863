#!/usr/bin/env bash
# "Benchmark your own policy": the planner, state-only ACT, image ACT and Diffusion Policy, trained on the same
# expert demonstrations (keyframe control) and evaluated by stock lerobot-eval on the same seeded episodes.
# Sized for a 2-core CPU (each training <= 10 min); pass a larger STEPS / N for real runs.
# Usage: benchmarks/image_policies.sh [OUT]  ->  OUT/table.md
set -euo pipefail
OUT=${1:-outputs/bench_images}
N=${N:-200}                # demonstrations (episodes)
STATE_STEPS=${STATE_STEPS:-1500}  # lerobot-train steps of state-only ACT (about 0.05 s a step here)
STEPS=${STEPS:-450}        # lerobot-train steps of image ACT (1-1.5 s a step on 2 busy cores)
DIFF_STEPS=${DIFF_STEPS:-180}  # ... and of Diffusion (about 3 s a step: two image frames per sample)
EVAL_N=${EVAL_N:-100}      # evaluation episodes (seeds EVAL_SEED ...)
EVAL_SEED=${EVAL_SEED:-100000}
export HF_HUB_OFFLINE=1 MUJOCO_GL=${MUJOCO_GL:-egl} OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
CAM=outputs/datasets/baxter_pnp_keyframe_front64   # the root configs/train_*_images.json train on
STATE=$OUT/datasets/keyframe_state
mkdir -p "$OUT"
timed() { local name=$1; shift; local t0=$SECONDS; "$@" > "$OUT/$name.log" 2>&1; echo "$name $((SECONDS - t0))" >> "$OUT/times.txt"; }

# The same demonstrations twice (cameras draw no random numbers): with a 64x64 front camera, and state only.
[ -f "$CAM/meta/info.json" ] || timed gen_images lerobot-pnp generate --repo_id local/baxter_pnp_keyframe_front64 \
  --root "$CAM" --num_episodes "$N" --env.cameras '[front]' --env.image_height 64 --env.image_width 64
[ -f "$STATE/meta/info.json" ] || timed gen_state lerobot-pnp generate --repo_id local/keyframe_state \
  --root "$STATE" --num_episodes "$N"

ACT_FLAGS=(--policy.type act --policy.device cpu --policy.push_to_hub false --policy.pretrained_backbone_weights null
  --policy.chunk_size 10 --policy.n_action_steps 1 --policy.dim_model 128 --policy.n_heads 4
  --policy.dim_feedforward 512 --policy.n_encoder_layers 2 --policy.n_decoder_layers 1 --policy.use_vae false
  --policy.dropout 0.0 --policy.optimizer_lr 0.0003)
common() { echo --num_workers 0 --batch_size 16 --steps "$1" --save_freq "$1" --log_freq 50 --env.type baxter_pnp \
  --env_eval_freq "$1" --eval.n_episodes 10 --eval.batch_size 10 --eval.use_async_envs false; }
[ -d "$OUT/planner" ] || timed train_planner lerobot-pnp train --dataset_repo_id local/keyframe_state \
  --dataset_root "$STATE" --epochs 300 --output_dir "$OUT/planner"
[ -d "$OUT/act_state" ] || timed train_act_state lerobot-train --dataset.repo_id local/keyframe_state \
  --dataset.root "$STATE" "${ACT_FLAGS[@]}" $(common "$STATE_STEPS") --output_dir "$OUT/act_state"
[ -d "$OUT/act_images" ] || timed train_act_images lerobot-train --config_path configs/train_act_images.json \
  $(common "$STEPS") --output_dir "$OUT/act_images"
[ -d "$OUT/diffusion_images" ] || timed train_diffusion_images lerobot-train \
  --config_path configs/train_diffusion_images.json $(common "$DIFF_STEPS") --output_dir "$OUT/diffusion_images"

for run in planner act_state act_images diffusion_images; do
  [ -f "$OUT/eval_$run/eval_info.json" ] || timed "eval_$run" lerobot-eval \
    --policy.path "$OUT/$run/checkpoints/last/pretrained_model" --env.type baxter_pnp --policy.device cpu \
    --eval.n_episodes "$EVAL_N" --eval.batch_size 10 --eval.use_async_envs false --seed "$EVAL_SEED" \
    --output_dir "$OUT/eval_$run"
done
python benchmarks/image_policies_table.py "$OUT" planner act_state act_images diffusion_images | tee "$OUT/table.md"
