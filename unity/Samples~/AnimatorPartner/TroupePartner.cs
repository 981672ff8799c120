// A partner for a humanoid character: every 1/30 s the Animator's bones go to a troupe session
// as t2m-22 joint positions (Unity's world: metres, Y up, left-handed), and the partner's joints
// come back a token (4 frames) at a time; they are shown as spheres, one per joint, played on
// the engine's clock (`PosePlayback`: interpolated between poses, never more than two tokens
// behind, whatever the frame rate).
//
// Setup: copy a bundle (the demo model, share/troupe/bundles/armflow-demo of an install, or
// onnx/bundles/armflow-demo of the repository) to Assets/StreamingAssets/armflow-demo, put this
// component on any GameObject and give it the actor's Animator (a Humanoid rig).
//
// Tested without the editor (tests/csharp.rs): this file, compiled against a stub UnityEngine,
// runs under Mono at 20, 60 and 144 frames a second for 60 s each with the demo model; the
// poses held stay bounded and the playback keeps pace with the actor. Not tested: the Unity
// editor and players themselves.
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
        private readonly float[] shown = new float[22 * 3];
        private PosePlayback playback;
        private Transform[] partner;
        private float clock;

        /// <summary>The partner's playback (its playhead and the poses it holds).</summary>
        public PosePlayback Playback { get { return playback; } }
        /// <summary>Actor frames given to the session so far.</summary>
        public long FramesFed { get; private set; }

        private void Start()
        {
            model = Model.Load(Path.Combine(Application.streamingAssetsPath, bundle));
            session = model.CreateSession(new SessionOptions { Seed = seed });
            session.SetCondition(rule);
            session.SetJointsFormat(new JointsFormat
            {
                Units = Units.Metres, Up = UpAxis.Y, Handedness = Handedness.Left, Fps = Rate,
            });
            playback = new PosePlayback(22 * 3, Rate);
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
            if (playback.Sample(Time.deltaTime, shown))
                for (int j = 0; j < 22; j++)
                    partner[j].position = new Vector3(shown[3 * j], shown[3 * j + 1], shown[3 * j + 2]);
        }

        // One frame of the actor in, the partner's poses that became ready handed to the playback.
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
            FramesFed++;
            playback.Push(poses, n);
        }

        private void OnDestroy()
        {
            if (session != null) session.Dispose();
            if (model != null) model.Dispose();
        }
    }
}
