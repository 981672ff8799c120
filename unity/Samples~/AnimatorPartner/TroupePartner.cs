// A partner for a humanoid character: every 1/30 s the actor Animator's bones go to a troupe
// session as t2m-22 joint positions (Unity's world: metres, Y up, left-handed), and the partner's
// joints come back a token (4 frames) at a time, played on the engine's clock (`PosePlayback`:
// interpolated between poses, never more than two tokens behind, whatever the frame rate). The
// partner drives a second Humanoid character: each shown pose is retargeted onto its skeleton
// (`Retargeter`), which gives every bone's local rotation and the hips' position. Without a
// partner character, spheres show the partner's joints.
//
// Setup: put this component on any GameObject, give it the actor's Animator and, for a driven
// partner, a second Humanoid Animator standing in its rest pose (a T-pose, no controller); it
// goes where the partner is, wherever it starts and whatever its armature's scale. The model: the demo bundle ships with this sample as one archive
// (armflow-demo.bytes, a TextAsset): assign it to `bundleArchive`, which works on every platform,
// Android included. Or leave it empty and put a bundle under Assets/StreamingAssets: a folder on
// desktop players; on Android, whose StreamingAssets lie compressed inside the APK, the archive
// `<bundle>.tar`, read with UnityWebRequest.
//
// Tested without the editor (tests/csharp.rs): this file, compiled against a stub UnityEngine,
// runs under Mono at 20, 60 and 144 frames a second for 60 s each with the demo model, loaded
// from a folder, from a TextAsset and through UnityWebRequest; the poses held stay bounded, the
// playback keeps pace with the actor and the partner character's bones point where the
// partner's joints are. Not tested: the Unity editor and players themselves.
using System.Collections;
using System.IO;
using System.Text;
using UnityEngine;
using UnityEngine.Networking;

namespace Troupe.Samples
{
    public sealed class TroupePartner : MonoBehaviour
    {
        [Tooltip("The actor: a Humanoid Animator.")]
        public Animator actor;
        [Tooltip("The partner: a Humanoid Animator in its rest pose; empty shows spheres.")]
        public Animator partnerCharacter;
        [Tooltip("The bundle as one tar archive (armflow-demo.bytes); empty reads StreamingAssets.")]
        public TextAsset bundleArchive;
        [Tooltip("A bundle under StreamingAssets (a folder, or <name>.tar on Android).")]
        public string bundle = "armflow-demo";
        [Tooltip("One of the bundle's rules: mirror, follow or keep-away for the demo model.")]
        public string rule = "mirror";
        public ulong seed = 7;
        [Tooltip("Retargeting onto the partner character: NoLimbIk aims every bone along the partner's, leaving hands and feet where the proportions put them; NoFootLock lets feet slide.")]
        public RetargetFlags retargetFlags = RetargetFlags.None;

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
        // The same joints by their t2m-22 names, for the partner character's joint map.
        private static readonly string[] T2mNames =
        {
            "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle",
            "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head",
            "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
        };
        private const float Rate = 30f;

        private Model model;
        private Session session;
        private readonly float[] frame = new float[22 * 3];
        private float[] poses = new float[8 * 22 * 3];
        private readonly float[] shown = new float[22 * 3];
        private PosePlayback playback;
        private Transform[] spheres;
        private Rig rig;
        private Retargeter retargeter;
        private Transform[] rigBones;
        private float[] rotations;
        private readonly float[] rootTranslation = new float[3];
        private float clock;

        /// <summary>The partner's playback (its playhead and the poses it holds); null until the
        /// model has loaded.</summary>
        public PosePlayback Playback { get { return playback; } }
        /// <summary>Actor frames given to the session so far.</summary>
        public long FramesFed { get; private set; }
        /// <summary>The partner's joint positions last shown (22 * 3 floats).</summary>
        public float[] Shown { get { return shown; } }

        // A coroutine: on Android the bundle is read from the APK before anything starts.
        private IEnumerator Start()
        {
            if (bundleArchive != null)
            {
                model = Model.LoadMemory(bundleArchive.bytes);
            }
            else if (Application.streamingAssetsPath.Contains("://"))
            {
                // Android: StreamingAssets is a URL into the APK, not a folder.
                using (var request = UnityWebRequest.Get(Application.streamingAssetsPath + "/" + bundle + ".tar"))
                {
                    yield return request.SendWebRequest();
                    if (request.result != UnityWebRequest.Result.Success)
                    {
                        Debug.LogError("troupe: cannot read " + bundle + ".tar from StreamingAssets: " + request.error);
                        yield break;
                    }
                    model = Model.LoadMemory(request.downloadHandler.data);
                }
            }
            else
            {
                model = Model.Load(Path.Combine(Application.streamingAssetsPath, bundle));
            }
            var format = new JointsFormat { Units = Units.Metres, Up = UpAxis.Y, Handedness = Handedness.Left, Fps = Rate };
            session = model.CreateSession(new SessionOptions { Seed = seed });
            session.SetCondition(rule);
            session.SetJointsFormat(format);
            if (partnerCharacter != null)
            {
                DriveCharacter(partnerCharacter, format);
            }
            else
            {
                spheres = new Transform[22];
                for (int j = 0; j < 22; j++)
                {
                    var sphere = GameObject.CreatePrimitive(PrimitiveType.Sphere);
                    sphere.transform.localScale = Vector3.one * 0.06f;
                    sphere.name = "partner joint " + j;
                    spheres[j] = sphere.transform;
                }
            }
            playback = new PosePlayback(22 * 3, Rate);
        }

        // The partner character's skeleton as a rig (docs/RIGS.md): its hips (in the world) and
        // every bone below (local to its parent), in their rest pose, in metres, with a joint
        // map from its Humanoid bones; a retargeter then turns each pose into the hips' place
        // and turn and every other bone's local rotation.
        private void DriveCharacter(Animator character, JointsFormat format)
        {
            Transform hips = character.GetBoneTransform(HumanBodyBones.Hips);
            var bones = new System.Collections.Generic.List<Transform>();
            var names = new System.Collections.Generic.Dictionary<Transform, string>();
            var json = new StringBuilder("{\"name\": \"partner\", \"units\": \"meters\", \"up\": \"y\", \"handedness\": \"left\", \"joints\": [");
            var stack = new System.Collections.Generic.Stack<Transform>();
            stack.Push(hips);
            while (stack.Count > 0)
            {
                Transform bone = stack.Pop();
                // Names must be unique in a rig; a bone's index keeps them so.
                string name = "b" + bones.Count + ":" + bone.name;
                names[bone] = name;
                // In metres whatever the armature's scale: the hips in the world, each other bone
                // in its parent's frame.
                Vector3 p = bone == hips ? bone.position : Quaternion.Inverse(bone.parent.rotation) * (bone.position - bone.parent.position);
                Quaternion q = bone == hips ? bone.rotation : bone.localRotation;
                json.Append(bones.Count == 0 ? "" : ", ").Append("{\"name\": ").Append(Quote(name))
                    .Append(", \"parent\": ").Append(bone == hips ? "null" : Quote(names[bone.parent]))
                    .Append(", \"offset\": [").Append(F(p.x)).Append(", ").Append(F(p.y)).Append(", ").Append(F(p.z))
                    .Append("], \"rotation\": [").Append(F(q.w)).Append(", ").Append(F(q.x)).Append(", ")
                    .Append(F(q.y)).Append(", ").Append(F(q.z)).Append("]}");
                bones.Add(bone);
                for (int c = bone.childCount - 1; c >= 0; c--) stack.Push(bone.GetChild(c));
            }
            json.Append("]}");
            var map = new StringBuilder("{\"skeleton\": \"t2m22\", \"joints\": {");
            for (int j = 0; j < 22; j++)
            {
                Transform bone = character.GetBoneTransform(Bones[j]);
                map.Append(j == 0 ? "" : ", ").Append(Quote(T2mNames[j])).Append(": [")
                    .Append(bone != null && names.ContainsKey(bone) ? Quote(names[bone]) : "").Append("]");
            }
            map.Append("}}");
            rig = Rig.FromJson(json.ToString(), map.ToString());
            retargeter = new Retargeter(rig, format, retargetFlags);
            rigBones = bones.ToArray();
            rotations = new float[rigBones.Length * 4];
        }

        private static string F(float v) { return v.ToString("R", System.Globalization.CultureInfo.InvariantCulture); }
        private static string Quote(string s) { return "\"" + s.Replace("\\", "\\\\").Replace("\"", "\\\"") + "\""; }

        private void Update()
        {
            if (playback == null) return; // still loading
            clock += Time.deltaTime;
            while (clock >= 1f / Rate)
            {
                clock -= 1f / Rate;
                Sample();
            }
            if (!playback.Sample(Time.deltaTime, shown)) return;
            if (retargeter != null)
            {
                // The rig's root (the hips) lives in the world; every other bone is local to its parent.
                int root = retargeter.Push(shown, rotations, rootTranslation);
                for (int b = 0; b < rigBones.Length; b++)
                {
                    var q = new Quaternion(rotations[4 * b + 1], rotations[4 * b + 2], rotations[4 * b + 3], rotations[4 * b]);
                    if (b == 0) rigBones[b].rotation = q;
                    else rigBones[b].localRotation = q;
                }
                var t = new Vector3(rootTranslation[0], rootTranslation[1], rootTranslation[2]);
                if (root == 0) rigBones[0].position = t;
                else rigBones[root].localPosition = Quaternion.Inverse(rigBones[root].parent.rotation) * t;
            }
            else
            {
                for (int j = 0; j < 22; j++)
                    spheres[j].position = new Vector3(shown[3 * j], shown[3 * j + 1], shown[3 * j + 2]);
            }
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
            if (retargeter != null) retargeter.Dispose();
            if (rig != null) rig.Dispose();
            if (session != null) session.Dispose();
            if (model != null) model.Dispose();
        }
    }
}
