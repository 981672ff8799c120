// A partner for a humanoid character: every 1/30 s the Animator's bones go to a troupe session
// as t2m-22 joint positions (Unity's world: metres, Y up, left-handed), and the partner's joints
// come back a token (4 frames) at a time; they are shown as spheres, one per joint.
//
// Setup: copy a bundle (the demo model, share/troupe/bundles/armflow-demo of an install, or
// onnx/bundles/armflow-demo of the repository) to Assets/StreamingAssets/armflow-demo, put this
// component on any GameObject and give it the actor's Animator (a Humanoid rig).
//
// Not run in the Unity editor by troupe's tests: the binding it uses is tested under Mono
// (tests/csharp.rs); this file is a starting point, not a tested product.
using System.Collections.Generic;
using System.IO;
using UnityEngine;

namespace Troupe.Samples
{
    public sealed class TroupePartner : MonoBehaviour
    {
        [Tooltip("The actor: a Humanoid Animator.")]
        public Animator actor;
        [Tooltip("A bundle folder under StreamingAssets.")]
        public string bundle = "armflow-demo";
        [Tooltip("One of the bundle's rules: mirror, follow or keep-away for the demo model.")]
        public string rule = "mirror";
        public ulong seed = 7;

        // t2m-22's joints in order, as Humanoid bones (UpperChest falls back to Chest, toes to feet).
        private static readonly HumanBodyBones[] Bones =
        {
            HumanBodyBones.Hips, HumanBodyBones.LeftUpperLeg, HumanBodyBones.RightUpperLeg, HumanBodyBones.Spine,
            HumanBodyBones.LeftLowerLeg, HumanBodyBones.RightLowerLeg, HumanBodyBones.Chest, HumanBodyBones.LeftFoot,
            HumanBodyBones.RightFoot, HumanBodyBones.UpperChest, HumanBodyBones.LeftToes, HumanBodyBones.RightToes,
            HumanBodyBones.Neck, HumanBodyBones.LeftShoulder, HumanBodyBones.RightShoulder, HumanBodyBones.Head,
            HumanBodyBones.LeftUpperArm, HumanBodyBones.RightUpperArm, HumanBodyBones.LeftLowerArm,
            HumanBodyBones.RightLowerArm, HumanBodyBones.LeftHand, HumanBodyBones.RightHand,
        };
        private static readonly HumanBodyBones[] Fallback =
        {
            HumanBodyBones.Hips, HumanBodyBones.Hips, HumanBodyBones.Hips, HumanBodyBones.Hips,
            HumanBodyBones.LeftUpperLeg, HumanBodyBones.RightUpperLeg, HumanBodyBones.Spine, HumanBodyBones.LeftLowerLeg,
            HumanBodyBones.RightLowerLeg, HumanBodyBones.Chest, HumanBodyBones.LeftFoot, HumanBodyBones.RightFoot,
            HumanBodyBones.Chest, HumanBodyBones.Neck, HumanBodyBones.Neck, HumanBodyBones.Neck,
            HumanBodyBones.Chest, HumanBodyBones.Chest, HumanBodyBones.LeftUpperArm, HumanBodyBones.RightUpperArm,
            HumanBodyBones.LeftLowerArm, HumanBodyBones.RightLowerArm,
        };
        private const float Rate = 30f;

        private Model model;
        private Session session;
        private readonly float[] frame = new float[22 * 3];
        private float[] poses = new float[8 * 22 * 3];
        private readonly Queue<Vector3[]> ready = new Queue<Vector3[]>();
        private Transform[] partner;
        private float clock;

        private void Start()
        {
            model = Model.Load(Path.Combine(Application.streamingAssetsPath, bundle));
            session = model.CreateSession(new SessionOptions { Seed = seed });
            session.SetCondition(rule);
            session.SetJointsFormat(new JointsFormat
            {
                Units = Units.Metres, Up = UpAxis.Y, Handedness = Handedness.Left, Fps = Rate,
            });
            partner = new Transform[22];
            for (int j = 0; j < 22; j++)
            {
                var sphere = GameObject.CreatePrimitive(PrimitiveType.Sphere);
                sphere.transform.localScale = Vector3.one * 0.06f;
                sphere.name = "partner joint " + j;
                partner[j] = sphere.transform;
            }
        }

        private void Update()
        {
            clock += Time.deltaTime;
            while (clock >= 1f / Rate)
            {
                clock -= 1f / Rate;
                Sample();
            }
            if (ready.Count > 0)
            {
                Vector3[] pose = ready.Dequeue();
                for (int j = 0; j < 22; j++) partner[j].position = pose[j];
            }
        }

        // One frame of the actor in, the partner's poses that became ready queued.
        private void Sample()
        {
            for (int j = 0; j < 22; j++)
            {
                Transform bone = actor.GetBoneTransform(Bones[j]) ?? actor.GetBoneTransform(Fallback[j]);
                Vector3 p = bone.position;
                frame[3 * j] = p.x;
                frame[3 * j + 1] = p.y;
                frame[3 * j + 2] = p.z;
            }
            int n = session.JointsReadyAfter(1);
            if (poses.Length < n * 66) poses = new float[n * 66];
            n = session.StepJoints(frame, 1, poses);
            for (int i = 0; i < n; i++)
            {
                var pose = new Vector3[22];
                for (int j = 0; j < 22; j++)
                    pose[j] = new Vector3(poses[i * 66 + 3 * j], poses[i * 66 + 3 * j + 1], poses[i * 66 + 3 * j + 2]);
                ready.Enqueue(pose);
            }
        }

        private void OnDestroy()
        {
            if (session != null) session.Dispose();
            if (model != null) model.Dispose();
        }
    }
}
